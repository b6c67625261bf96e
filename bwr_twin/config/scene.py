"""Scenes: TOML files in scenes/ loaded into typed, validated, frozen configuration.

A scene names the machine, the reclaim path, the physics and control rates, the imperfect world
(encoders, disturbances, unmodelled plant effects) and the controller settings. Loading one runs
four parts, each of one job: the file's tables read (bwr_twin.config.scene_file), built into the
typed sections (bwr_twin.config.builder, against bwr_twin.config.sections), the rules across fields
(bwr_twin.config.rules) and the physical ranges (bwr_twin.config.bounds). A bad file raises
SceneError with one line naming the file, the key and the rule it broke. `overrides` (dotted keys,
as a sweep or the command line gives them) are applied before validation, so they are checked
exactly like the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bwr_twin.config.builder import build
from bwr_twin.config.rules import check_rules
from bwr_twin.config.scene_file import scene_tables
from bwr_twin.config.sections import Scene

__all__ = ["Scene", "load_scene"]


def load_scene(path: str | Path, overrides: dict[str, Any] | None = None) -> Scene:
    """Read, override and validate a scene file.

    Args:
        path: the TOML file. Relative paths inside it are relative to its folder. A top-level
            `extends = "other.toml"` reads that scene first and lays this file's tables over it,
            key by key; `extends` may also name a shipped scene ("heavy_reclaim"). Of keys
            that exclude each other (ALTERNATIVES: [path] or [reclaim], a windrow or a
            surface_file, one bench stop), the one this file gives replaces the base's; and
            `replace = ["digging", "plant.payload"]` takes those tables (or keys) from this file
            alone, dropping the base's where this file has none.
        overrides: dotted keys to replace before validation, e.g. {"simulation.seed": 3,
            "machine.mjcf": "/abs/heavy.xml"}; relative paths in them are relative to the cwd.
            One of ALTERNATIVES' keys replaces the others, as in a file that extends.
    """
    path = Path(path)
    scene = build(Scene, {"path": str(path), **scene_tables(path, overrides)}, path, "")
    check_rules(scene)
    return scene
