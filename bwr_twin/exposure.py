"""Who else can see a server of the twin (the replay, the OPC UA server): one on anything but
loopback says so, with its real addresses."""

from __future__ import annotations

import contextlib
import ipaddress
import socket

WILDCARDS = ("0.0.0.0", "::", "")
_UNROUTED_PROBE = ("192.0.2.1", 9)  # TEST-NET-1 (RFC 5737): a UDP connect picks a route, sends nothing


def exposure_warning(host: str, port: int) -> str | None:
    """A one-line warning if the replay at host:port can be reached from other machines, or None."""
    if host not in WILDCARDS:
        with contextlib.suppress(ValueError):
            if ipaddress.ip_address(host).is_loopback:
                return None
        if host == "localhost":
            return None
        return (f"warning: the replay is served on {host}, reachable from other machines on that network, "
                f"without a password: http://{host}:{port}")
    addresses = ", ".join(f"http://{address}:{port}" for address in network_addresses()) or "none found"
    return (f"warning: --host {host or '(all)'} serves the replay on every network interface, without a "
            f"password, to anyone who can reach this machine: {addresses}")


def network_addresses() -> list[str]:
    """This machine's IPv4 addresses other than loopback, as far as the standard library sees them."""
    found: list[str] = []
    with contextlib.suppress(OSError):
        for *_, sockaddr in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET):
            found.append(sockaddr[0])
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect(_UNROUTED_PROBE)
        found.append(probe.getsockname()[0])
    return [a for a in dict.fromkeys(found) if not ipaddress.ip_address(a).is_loopback]
