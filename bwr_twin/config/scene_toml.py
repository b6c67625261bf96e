"""A scene written back as a scene file: what `load_scene` reads gives the same scene again.

Used where the twin hands an engineer a scene to keep (the tuner's best scene). Paths are
written absolute; keys without a value (None) are left out, as the file would leave them.
"""

from __future__ import annotations

import json
import math
from typing import Any

from bwr_twin.config.scene import Scene

_TABLE_NAMES = {"trajectory": "path"}  # Scene field -> TOML table, as load_scene reads them


def scene_toml(scene: Scene, header: str = "") -> str:
    """The scene as TOML text, after `header` (written as comment lines)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for field, table in scene.to_dict().items():
        if field == "path":
            continue
        for entry in table if isinstance(table, list) else [table]:  # a list of tables: [[faults]]
            if not isinstance(entry, dict):
                continue
            name = _TABLE_NAMES.get(field, field)
            lines += ["", f"[[{name}]]" if isinstance(table, list) else f"[{name}]"]
            lines += [f"{key} = {_value(value)}" for key, value in entry.items() if value is not None]
    return "\n".join(lines).lstrip("\n") + "\n"


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"a scene holds no {value}")
        return repr(value)
    if isinstance(value, (int, str)):
        return json.dumps(value)  # a TOML basic string is a JSON string
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_value(v)}" for k, v in value.items() if v is not None) + " }"
    raise TypeError(f"no TOML for {type(value).__name__}")
