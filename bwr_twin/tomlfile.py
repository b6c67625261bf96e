"""The TOML files people write (scenes, sweeps, tunings, rule bases): read with one-line errors,
their keys reached by dotted name, and values written back as TOML that reads back exactly.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bwr_twin.errors import SceneError
from bwr_twin.textfile import read_text

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

MISSING = object()  # at_dotted's answer for a key the table does not have


def read_toml(path: Path, kind: str, check_text: Callable[[Path, str], None] | None = None) -> dict[str, Any]:
    """The file's tables; `kind` ("scene", "sweep", "rule base", ...) names it in the one-line
    SceneError of a missing, unreadable, binary or malformed file. `check_text(path, text)` runs on
    the text before it is parsed (a limit a parser would not see)."""
    if not path.is_file():
        raise SceneError(f"{path}: {kind} file not found")
    try:
        text = read_text(path)
        if check_text is not None:
            check_text(path, text)
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: malformed TOML: {exc}") from None
    except UnicodeDecodeError:
        raise SceneError(f"{path}: not a text file") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the {kind} file: {exc.strerror}") from None


def at_dotted(table: Any, dotted: str, missing: Any = MISSING) -> Any:
    """The value at a dotted key ("controller.output_gain"), `missing` where a table lacks it."""
    for name in dotted.split("."):
        if not isinstance(table, dict) or name not in table:
            return missing
        table = table[name]
    return table


def set_dotted(table: dict, dotted: str, value: Any) -> None:
    """Set a dotted key, making the tables on its way; ValueError naming the key on its way that
    holds a value, not a table."""
    *parents, key = dotted.split(".")
    for name in parents:
        table = table.setdefault(name, {})
        if not isinstance(table, dict):
            raise ValueError(f"'{name}' is not a table")
    table[key] = value


def toml_value(value: Any) -> str:
    """A TOML value: booleans, numbers (a float always with its '.' or exponent, read back
    exactly), strings, lists and tables (inline; None entries left out, as a file leaves them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML files here hold no {value}")
        return repr(float(value))  # a numpy float's repr names its type
    if isinstance(value, (int, str)):
        return json.dumps(value)  # a TOML basic string is a JSON string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items() if v is not None) + " }"
    raise TypeError(f"no TOML for {type(value).__name__}")
