"""Serve one run of a scene over OPC UA: the twin is the machine, the client the PLC.

    python -m bwr_twin.serve SCENE [--endpoint opc.tcp://127.0.0.1:4840] [--realtime [--speed X] | --lockstep]
        [--watchdog-periods N] [--users FILE] [--user-certificates PATH] [--certificate CERT --private-key KEY]
        [--out DIR [--overwrite] [--no-plots]] [--model MJCF] [--seed N]
    python -m bwr_twin.serve SCENE --nodeset FILE.xml [--overwrite]

SCENE is a scene file, or the name of a shipped one. The address space, modes, watchdog and
security are in docs/opcua.md. --nodeset writes the address space as a UA NodeSet2 file and
serves nothing. Bad input exits with status 2 and one line; Ctrl-C stops the server with
status 130, SIGTERM with 0.
"""

from __future__ import annotations

import argparse
import asyncio
import errno
import ipaddress
import re
import socket
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import exit_status, leave
from bwr_twin.serve import DEFAULT_WATCHDOG_PERIODS, LOCKSTEP, REALTIME, ServeError
from bwr_twin.sim.budget import FORCE_HELP

DEFAULT_ENDPOINT = "opc.tcp://127.0.0.1:4840"
DEFAULT_PORT = 4840  # OPC UA's registered port, when the URL gives none


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.serve", description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="scene TOML file, or a shipped scene's name, e.g. paper_individual_gains")
    parser.add_argument("--endpoint", default=DEFAULT_ENDPOINT,
                        help=f"opc.tcp://HOST:PORT (default {DEFAULT_ENDPOINT}, this machine only)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", action="store_true",
                      help="the client advances the twin with Step(n) (default)")
    mode.add_argument("--realtime", action="store_true", help="simulated time follows the wall clock once Start "
                      "is called")
    parser.add_argument("--speed", type=float, default=1.0,
                        help="real-time mode: simulated seconds per wall-clock second (default 1)")
    parser.add_argument("--watchdog-periods", type=int, default=DEFAULT_WATCHDOG_PERIODS, help="real-time mode: "
                        "control periods without a DriveSetpoint write before the drives go to zero; 0: no "
                        f"watchdog (default {DEFAULT_WATCHDOG_PERIODS})")
    parser.add_argument("--users", type=Path,
                        help="users file (python -m bwr_twin.serve.passwd NAME makes a line): writes and method "
                        "calls need one of them; anonymous sessions read only")
    parser.add_argument("--user-certificates", type=Path, metavar="PATH", help="trusted users' X.509 "
                        "certificates (a folder of .pem/.crt/.cer/.der, or one file): their holders log in with "
                        "them, as --users' users do with passwords; needs --certificate")
    parser.add_argument("--certificate", type=Path, help="server certificate (DER or PEM): Basic256Sha256, signed "
                        "and encrypted; needed, with --users, on any address but loopback")
    parser.add_argument("--private-key", type=Path, help="the certificate's private key (PEM)")
    parser.add_argument("--out", type=Path, help="write each completed path's results here, as bwr_twin.run does "
                        "(must not exist)")
    parser.add_argument("--overwrite", action="store_true", help="replace --out, a run directory the twin wrote, "
                        "or --nodeset, a file it wrote")
    parser.add_argument("--nodeset", type=Path, metavar="FILE.xml", help="write the address space as a UA "
                        "NodeSet2 file and exit, serving nothing")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures of --out")
    parser.add_argument("--model", help="machine MJCF replacing the scene's")
    parser.add_argument("--seed", type=int, help="disturbance seed replacing the scene's")
    parser.add_argument("--force", action="store_true", help=FORCE_HELP)
    args = parser.parse_args(argv)
    return exit_status(lambda: _serve(args), interrupted="interrupted: server stopped")


def _serve(args: argparse.Namespace) -> int:
    url, host, port = _endpoint(args.endpoint)
    if not args.realtime and args.speed != 1.0:
        raise ServeError("--speed applies to --realtime only")
    if not 0 < args.speed <= 1000:
        raise ServeError(f"--speed {args.speed:g}: must lie in (0, 1000]")
    if args.watchdog_periods < 0:
        raise ServeError(f"--watchdog-periods {args.watchdog_periods}: must be >= 0 (0: no watchdog)")
    from bwr_twin.shipped import find_scene

    scene_path = find_scene(args.scene)  # before the imports of asyncua and MuJoCo: bad input answers at once

    from bwr_twin.config.scene import load_scene
    from bwr_twin.ownership import check_output
    from bwr_twin.run import scene_overrides
    from bwr_twin.serve.announce import is_loopback
    from bwr_twin.serve.certificates import check_certificate
    from bwr_twin.serve.security import check_options, load_users
    from bwr_twin.serve.server import APPLICATION_URI, Options, export_nodeset, serve
    from bwr_twin.serve.user_certificates import load_user_certificates
    from bwr_twin.sim.budget import check_scenes

    options = Options(url=url, host=host, port=port, mode=REALTIME if args.realtime else LOCKSTEP,
                      speed=args.speed, watchdog_periods=args.watchdog_periods, users=args.users,
                      user_certificates=args.user_certificates, certificate=args.certificate,
                      private_key=args.private_key, out=args.out, overwrite=args.overwrite, plots=not args.no_plots)
    if args.nodeset is not None:
        if args.out is not None:
            raise ServeError(f"--nodeset {args.nodeset} writes the address space and serves nothing: --out does "
                             "not apply")
        scene = load_scene(scene_path, scene_overrides(args.model, args.seed))
        check_scenes([scene], where=scene.path, out_dir=args.nodeset.parent, force=args.force)
        check_output(args.nodeset, "nodeset", overwrite=args.overwrite, inputs=scene.input_files, option="--nodeset")
        return asyncio.run(export_nodeset(scene, options, args.nodeset))
    check_options(url=url, loopback=is_loopback(host), users_file=args.users, certificate=args.certificate,
                  private_key=args.private_key, user_certificates=args.user_certificates)
    if args.certificate is not None:
        check_certificate(args.certificate, args.private_key, APPLICATION_URI)
    _check_listenable(url, host, port)
    if args.users is not None:
        load_users(args.users)  # a bad line stops here, before any work
    if args.user_certificates is not None:
        load_user_certificates(args.user_certificates)
    scene = load_scene(scene_path, scene_overrides(args.model, args.seed))
    check_scenes([scene], where=scene.path, out_dir=args.out or Path.cwd(), force=args.force)  # the run it serves
    return asyncio.run(serve(scene, options))


def _check_listenable(url: str, host: str, port: int) -> None:
    """ServeError at once if the endpoint's address cannot be bound (the server binds it only after
    seconds of start-up)."""
    try:
        family, kind, protocol, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as exc:
        raise ServeError(f"--endpoint {url}: cannot resolve {host} ({exc.strerror})") from None
    with socket.socket(family, kind, protocol) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as asyncio's server does
        try:
            probe.bind(address)
        except OSError as exc:
            reason = f"port {port} is in use" if exc.errno == errno.EADDRINUSE else exc.strerror
            raise ServeError(f"--endpoint {url}: cannot listen ({reason})") from None


def _endpoint(text: str) -> tuple[str, str, int]:
    """(url, host, port) of an opc.tcp URL; ServeError naming the option if it is not one."""
    usage = f"--endpoint {text}: expected opc.tcp://HOST:PORT, e.g. {DEFAULT_ENDPOINT}"
    scheme, separator, rest = text.partition("://")
    if scheme != "opc.tcp" or not separator:
        raise ServeError(usage)
    address = _ADDRESS.fullmatch(rest.removesuffix("/"))
    if address is None:
        if rest.startswith("["):
            raise ServeError(f"{usage}; an IPv6 address is [ADDRESS]:PORT, e.g. opc.tcp://[::1]:4840")
        raise ServeError(usage + ("; an IPv6 address goes in brackets, e.g. opc.tcp://[::1]:4840"
                                  if rest.count(":") > 1 else ""))
    host = address["ipv6"] if address["ipv6"] is not None else address["host"]
    if address["ipv6"] is not None:
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise ServeError(f"--endpoint {text}: [{host}] is not an IPv6 address") from None
    port = DEFAULT_PORT if address["port"] is None else int(address["port"] or 0)
    if not 1 <= port <= 65535:
        raise ServeError(f"{usage} (port must be 1-65535)")
    return f"opc.tcp://{f'[{host}]' if ':' in host else host}:{port}", host, port


# HOST:PORT or [IPV6]:PORT, the port optional; a host name holds no brackets, colons or slashes.
_ADDRESS = re.compile(r"(?:\[(?P<ipv6>[^\[\]/]*)\]|(?P<host>[^\[\]:/@?#\s]+))(?::(?P<port>[0-9]*))?")


if __name__ == "__main__":
    leave(main())
