"""Make a users-file line for the OPC UA server.

    python -m bwr_twin.serve.passwd NAME >> users.txt

Asks for the password (twice on a terminal; one line of stdin otherwise) and prints
`NAME:pbkdf2_sha256$...`. The password itself is never stored.
"""

from __future__ import annotations

import getpass
import sys

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, exit_status, leave
from bwr_twin.serve.security import hash_password


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.serve.passwd", description=__doc__.split("\n\n")[0])
    parser.add_argument("name", help="user name (no ':')")
    args = parser.parse_args(argv)
    return exit_status(lambda: _line(args.name))


def _line(name: str) -> int:
    if not name or ":" in name:
        raise BwrError(f"user name {name!r}: must be non-empty and hold no ':'")
    if sys.stdin.isatty():
        password = getpass.getpass(f"password for {name}: ")
        if getpass.getpass("again: ") != password:
            raise BwrError("the two passwords differ; nothing printed")
    else:
        password = sys.stdin.readline().rstrip("\n")
    if not password:
        raise BwrError("empty password; nothing printed")
    print(f"{name}:{hash_password(password)}")
    return 0


if __name__ == "__main__":
    leave(main())
