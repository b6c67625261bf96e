"""A scene written back as a scene file: what `load_scene` reads gives the same scene again.

Used where the twin hands an engineer a scene to keep (the tuner's best scene). Paths are
written absolute; keys without a value (None) are left out, as the file would leave them.
"""

from __future__ import annotations

from bwr_twin.config.sections import TABLE_NAMES, Scene
from bwr_twin.tomlfile import toml_value


def scene_toml(scene: Scene, header: str = "") -> str:
    """The scene as TOML text, after `header` (written as comment lines)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for field, table in scene.to_dict().items():
        if field == "path":
            continue
        for entry in table if isinstance(table, list) else [table]:  # a list of tables: [[faults]]
            if not isinstance(entry, dict):
                continue
            name = TABLE_NAMES.get(field, field)
            lines += ["", f"[[{name}]]" if isinstance(table, list) else f"[{name}]"]
            lines += [f"{key} = {toml_value(value)}" for key, value in entry.items() if value is not None]
    return "\n".join(lines).lstrip("\n") + "\n"

