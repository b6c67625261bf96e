"""What counts as a number in the files the twin reads (TOML and JSON): one rule for every reader."""

from __future__ import annotations

import math
from typing import Any


def is_number(value: Any) -> bool:
    """A finite TOML (or JSON) integer or float. TOML writes nan and inf, which no setting may be;
    Python's bool is an int, but true is not a number."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def is_integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def reads_as_number(text: str) -> bool:
    """Whether a CSV cell reads as a number (Python's float syntax, nan and inf included)."""
    try:
        float(text)
    except ValueError:
        return False
    return True
