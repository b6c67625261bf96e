"""What the server says at start: what it exposes, to whom, and what a client may change."""

from __future__ import annotations

from bwr_twin.exposure import WILDCARDS, exposure_warning, network_addresses


def is_loopback(host: str) -> bool:
    """True if `host` reaches this machine only (the replay's rule: loopback addresses, localhost)."""
    return exposure_warning(host, 0) is None


def exposure_lines(*, url: str, host: str, port: int, mode: str, policies: list[str], access: str,
                   writable: list[str], methods: list[str], namespace: str) -> list[str]:
    """The lines printed once the server listens; a warning first if other machines can reach it."""
    lines = []
    if host in WILDCARDS:
        addresses = ", ".join(f"opc.tcp://{a}:{port}" for a in network_addresses()) or "none found"
        lines.append(f"warning: {url} serves the twin on every network interface, to anyone who can reach "
                     f"this machine: {addresses}")
    elif not is_loopback(host):
        lines.append(f"warning: the twin is served on {host}, reachable from other machines on that network: "
                     f"{url}")
    reach = "loopback: this machine only" if is_loopback(host) else "other machines can connect"
    lines += [
        f"endpoint: {url} ({reach})",
        f"mode: {mode}",
        f"security policies: {', '.join(policies)}",
        access,
        f"writable: {', '.join(writable)}",
        f"methods: {', '.join(methods)}",
        f"namespace: {namespace}",
        "Ctrl-C stops the server",
    ]
    return lines
