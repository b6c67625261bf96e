"""The command lines' argument parser: a bad option is one line, as any other bad input.

argparse prints its usage and then the error, four or five lines; every command of the twin
answers bad input with one line `error: <what>: <what is wrong>` and exit status 2
(docs/reliability.md). `--help` still prints the usage in full.
"""

from __future__ import annotations

import argparse
import re
import sys
from typing import NoReturn

# What argparse takes for a value rather than an option: a negative number as float() reads it,
# -inf and -nan included (so that the command, not the parser, says they are not finite).
NEGATIVE_NUMBER = re.compile(r"^-(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|inf|infinity|nan)$", re.IGNORECASE)


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr, pointing at --help, and status 2.
    Subcommands' parsers are of the same class (argparse makes them with type(self)).

    A negative number in any notation float() reads (-1e-3, -.5, -2., -inf) is a value, not an option:
    argparse alone takes only -1 and -0.5 for numbers."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())  # argparse wraps some messages over lines
        print(f"error: {self.prog}: {text} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)
