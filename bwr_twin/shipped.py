"""The files the package ships: machine models, scenes, sweeps and rule bases.

They are found through the installed package, so a command works from any folder and from a
non-editable install. In the checkout they are the top-level folders mjcf/ and scenes/, which
pyproject.toml ships as the packages `bwr_twin.mjcf` and `bwr_twin.scenes`: in a wheel they sit
inside bwr_twin/, and an editable install maps them to the checkout's folders. A scene or sweep
on the command line is a file path, or the name of a shipped one: `paper_individual_gains`,
`sweeps/paper_monte_carlo`.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from bwr_twin.errors import SceneError

PACKAGE = Path(str(files("bwr_twin")))
MJCF = Path(str(files("bwr_twin.mjcf")))
SCENES = Path(str(files("bwr_twin.scenes")))
RULE_BASES = SCENES / "rulebases"
SCENE_DEFAULTS = SCENES / "defaults" / "scene_defaults.toml"  # a number a scene leaves out, with its source
SCENARIOS = SCENES / "scenarios"  # what generated scenarios draw from
DEFAULT_SCENE = SCENES / "paper_individual_gains.toml"


def find_scene(text: str | Path) -> Path:
    """A scene or sweep file: the path itself if it exists, else the shipped file of that name.

    Raises SceneError listing the shipped scenes if neither exists.
    """
    path = Path(text)
    if path.exists():
        return path
    for candidate in (SCENES / path, SCENES / f"{path}.toml"):
        if candidate.is_file():
            return candidate
    shipped = ", ".join(sorted(str(p.relative_to(SCENES).with_suffix("")) for p in SCENES.rglob("*.toml")
                               if p.parent.name not in ("rulebases", "defaults", "scenarios")))
    raise SceneError(f"{text}: scene file not found, nor a shipped scene or sweep of that name (shipped: {shipped})")
