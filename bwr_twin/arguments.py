"""The command lines' argument parser: a bad option is one line, as any other bad input.

argparse prints its usage and then the error, four or five lines; every command of the twin
answers bad input with one line `error: <what>: <what is wrong>` and exit status 2
(docs/reliability.md). `--help` still prints the usage in full.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr, pointing at --help, and status 2.
    Subcommands' parsers are of the same class (argparse makes them with type(self))."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())  # argparse wraps some messages over lines
        print(f"error: {self.prog}: {text} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)
