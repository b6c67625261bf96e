"""Sweep files: one base scene and what to vary, expanded into the runs of a batch.

A sweep file is TOML. `scene` names the base scene, `seeds` the disturbance seeds, and the
`[vary]` table any scene key (dotted, as in the scene file) with a list of values or a range:

    scene = "../paper_individual_gains.toml"  # relative to this file
    seeds = 32                                # seeds 1..32, or a list: [1, 7, 42]

    [vary]
    controller.output_gain.travel = [0.005, 0.01, 0.02]                   # one axis of a per-axis list
    controller.output_gain.slew = { start = 0.02, stop = 0.08, num = 4 }  # evenly spaced, both ends
    disturbance.hold_time = { start = 0.01, stop = 0.05, step = 0.02 }    # stop kept if on the grid
    machine.mjcf = ["../../mjcf/bwr.xml", "../../mjcf/bwr_heavy.xml"]   # relative to this file

The runs are the cartesian product of the varied keys, in file order with the first outermost,
and of the seeds, innermost. Every generated scene is validated like a scene file before any run
starts; what only the simulation can find (an unreachable via point, a divergence) fails that
run alone, at run time.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.config.scene import Scene, load_scene
from bwr_twin.config.scene_file import PATH_KEYS
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import AXES
from bwr_twin.tomlfile import at_dotted, read_toml
from bwr_twin.values import is_integer, is_number

_TOP_LEVEL_KEYS = ("scene", "seeds", "vary")
_RANGE_KEYS = ("start", "stop", "num", "step")
_RANGE_DIGITS = 12  # significant digits kept of a range value: 0.1 + 0.2 gives 0.3
_UNSAFE_IN_NAME = re.compile(r"[^A-Za-z0-9._=+#-]")
MAX_RUNS = 20_000  # a sweep plans at most this many runs without --force (about 15 s of planning)
PLANNABLE_RUNS = 1_000_000  # and never more: their plan alone would take gigabytes
_MAX_SETTING_CHARS = 160  # of a run directory's name; the index keeps truncated names unique


@dataclass(frozen=True)
class PlannedRun:
    """One run of a sweep: a validated scene and where its results go."""

    run_id: str  # its directory's name: index, varied values, seed; stable while the sweep file is
    parameters: dict[str, Any]  # varied key -> value as the sweep file gives it (the seed aside)
    value_labels: dict[str, str]  # varied key -> its value as a short text: "0.01", "bwr_heavy"
    scene: Scene

    @property
    def seed(self) -> int:
        return self.scene.simulation.seed


@dataclass(frozen=True)
class Sweep:
    """A sweep file expanded: its runs in order, each with its scene."""

    path: Path  # the sweep file
    keys: tuple[str, ...]  # varied scene keys in file order, without the seed
    runs: tuple[PlannedRun, ...]

    def digest(self) -> str:
        """sha256 of what the sweep plans, each run's name and scene: two sweeps with the same
        digest write the same run directories."""
        plan = [[run.run_id, run.scene.to_dict()] for run in self.runs]
        return hashlib.sha256(json.dumps(plan, sort_keys=True).encode()).hexdigest()

    def grid_keys(self) -> tuple[str, str] | None:
        """The two keys of a 2-D grid of numbers (for a heat map), if that is what this sweep is."""
        if len(self.keys) != 2:
            return None
        numeric = all(is_number(run.parameters[key]) for run in self.runs for key in self.keys)
        return (self.keys[0], self.keys[1]) if numeric else None


def load_sweep(path: str | Path, *, max_runs: int | None = MAX_RUNS) -> Sweep:
    """Read and validate a sweep file and every scene it generates.

    Raises SceneError naming the sweep file and the key at fault, or the count of runs if it
    exceeds `max_runs` (None: only PLANNABLE_RUNS), before any is planned.
    """
    path = Path(path)
    raw = read_toml(path, "sweep")
    unknown = sorted(set(raw) - set(_TOP_LEVEL_KEYS))
    if unknown:
        raise SceneError(f"{path}: unknown key '{unknown[0]}' (valid here: {', '.join(_TOP_LEVEL_KEYS)})")
    if "scene" not in raw:
        raise SceneError(f"{path}: missing key 'scene' (the base scene file)")
    if not isinstance(raw["scene"], str):
        raise SceneError(f"{path}: 'scene' must be a file path, got {raw['scene']!r}")
    base_path = (path.parent / raw["scene"]).resolve()
    if not base_path.is_file():
        raise SceneError(f"{path}: 'scene' names a file that does not exist: {base_path}")
    base = _scene(path, base_path, {}).to_dict()
    varied = _varied(raw.get("vary", {}), path, "vary")
    if "simulation.seed" in varied:
        raise SceneError(f"{path}: 'vary.simulation.seed': give the seeds as the top-level 'seeds'")
    components = axis_components(varied, base, path)
    seeds = _seeds(raw["seeds"], path) if "seeds" in raw else [None]

    keys = tuple(varied)
    count = math.prod(len(values) for values in varied.values()) * len(seeds)
    limit = PLANNABLE_RUNS if max_runs is None else min(max_runs, PLANNABLE_RUNS)
    if count > limit:
        sizes = " x ".join(f"{len(values)} ({key})" for key, values in [*varied.items(), ("seeds", seeds)])
        hint = "pass --force to plan it anyway" if limit < PLANNABLE_RUNS else "split it into several sweeps"
        raise SceneError(f"{path}: expands to {count} runs = {sizes}, more than {limit}; {hint}")
    combinations = itertools.product(*varied.values(), seeds)
    width = max(4, len(str(count - 1)))
    runs = []
    for index, (*values, seed) in enumerate(combinations):
        parameters = dict(zip(keys, values))
        overrides = scene_overrides(parameters, components, base, path.parent)
        if seed is not None:
            overrides["simulation.seed"] = seed
        scene = _scene(path, base_path, overrides)
        labels = {key: _value_text(value, varied[key]) for key, value in parameters.items()}
        run_id = _run_id(index, width, labels, scene.simulation.seed)
        runs.append(PlannedRun(run_id, parameters, labels, scene))
    return Sweep(path=path, keys=keys, runs=tuple(runs))


def parameter_label(key: str) -> str:
    """A varied key without its table, as run names and plots show it: 'output_gain.travel'."""
    return key.split(".", 1)[-1]


def _scene(sweep_path: Path, base_path: Path, overrides: dict[str, Any]) -> Scene:
    try:
        return load_scene(base_path, overrides)
    except SceneError as exc:
        raise SceneError(f"{sweep_path}: {exc}") from None


def _varied(table: Any, path: Path, where: str) -> dict[str, list]:
    """Flatten [vary] into {dotted scene key: values}; TOML's dotted keys arrive as nested tables."""
    if not isinstance(table, dict):
        raise SceneError(f"{path}: '{where}' must be a table")
    if not table and where != "vary":
        raise SceneError(f"{path}: '{where}' is an empty table")
    varied: dict[str, list] = {}
    for name, value in table.items():
        key = f"{where}.{name}"
        if isinstance(value, list):
            varied[key] = _checked_list(value, path, key)
        elif isinstance(value, dict) and "start" in value:
            varied[key] = _checked_list(_range(value, path, key), path, key)
        elif isinstance(value, dict):
            varied.update(_varied(value, path, key))
        else:
            raise SceneError(f"{path}: '{key}' must be a list of values or a range "
                             f"{{ start, stop, num or step }}, got {value!r}")
    return {key.removeprefix("vary."): values for key, values in varied.items()}


def _checked_list(values: list, path: Path, key: str) -> list:
    if not values:
        raise SceneError(f"{path}: '{key}' is an empty list: give at least one value")
    seen = set()
    for value in values:
        marker = json.dumps(value, sort_keys=True)  # hashable, and 1 == 1.0 as in the scene
        if marker in seen or (is_number(value) and json.dumps(float(value)) in seen):
            raise SceneError(f"{path}: '{key}' lists {value!r} twice")
        seen.add(marker)
        if is_number(value):
            seen.add(json.dumps(float(value)))
    return values


def _range(spec: dict[str, Any], path: Path, key: str) -> list[float]:
    """{start, stop, num}: num values from start to stop, both included;
    {start, stop, step}: start, start + step, ... up to stop."""
    unknown = sorted(set(spec) - set(_RANGE_KEYS))
    if unknown:
        raise SceneError(f"{path}: unknown key '{key}.{unknown[0]}' (valid here: {', '.join(_RANGE_KEYS)})")
    for bound in ("start", "stop"):
        if bound not in spec:
            raise SceneError(f"{path}: range '{key}' needs '{bound}'")
        if not is_number(spec[bound]):
            raise SceneError(f"{path}: '{key}.{bound}' must be a finite number, got {spec[bound]!r}")
    if ("num" in spec) == ("step" in spec):
        raise SceneError(f"{path}: range '{key}' needs exactly one of 'num' and 'step'")
    start, stop = float(spec["start"]), float(spec["stop"])
    if "num" in spec:
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= PLANNABLE_RUNS:
            raise SceneError(f"{path}: '{key}.num' must be an integer from 1 to {PLANNABLE_RUNS}, got {num!r}")
        values = np.linspace(start, stop, num)
    else:
        step = spec["step"]
        if not is_number(step) or not step > 0:
            raise SceneError(f"{path}: '{key}.step' must be a number > 0, got {step!r}")
        if stop < start:
            raise SceneError(f"{path}: range '{key}' with a step needs stop >= start, got {start} > {stop}")
        count = math.floor((stop - start) / step + 1e-9) + 1  # 1e-9: keep a stop that lies on the grid
        if count > PLANNABLE_RUNS:
            raise SceneError(f"{path}: range '{key}' gives {count:.3g} values, more than a sweep can run "
                             f"({PLANNABLE_RUNS}); check its step")
        values = start + step * np.arange(count)
    return [float(f"{v:.{_RANGE_DIGITS}g}") for v in values]


def _seeds(value: Any, path: Path) -> Sequence[int]:
    if is_integer(value) and value >= 1:
        return range(1, value + 1)  # counted before it is expanded
    if isinstance(value, list) and value and all(is_integer(v) and v >= 0 for v in value):
        return _checked_list(value, path, "seeds")
    raise SceneError(f"{path}: 'seeds' must be a count (an integer >= 1) or a list of integers >= 0, "
                     f"got {value!r}")


def axis_components(varied: dict[str, list], base: dict[str, Any], path: Path) -> dict[str, tuple[str, int]]:
    """Varied keys that name one axis of a per-axis list: {key: (list key, axis index)}."""
    components = {}
    for key in varied:
        parent, _, last = key.rpartition(".")
        if last in AXES and _is_vector(at_dotted(base, parent, None)):
            if parent in varied:
                raise SceneError(f"{path}: 'vary' has both '{parent}' and its axis '{key}': "
                                 "vary one or the other")
            components[key] = (parent, AXES.index(last))
    return components


def scene_overrides(parameters: dict[str, Any], components: dict[str, tuple[str, int]], base: dict[str, Any],
               folder: Path) -> dict[str, Any]:
    """Scene overrides for one combination of varied values."""
    overrides: dict[str, Any] = {}
    for key, value in parameters.items():
        if key in components:
            parent, axis = components[key]
            overrides.setdefault(parent, list(at_dotted(base, parent)))[axis] = value
        elif key.rsplit(".", 1)[-1] in PATH_KEYS and isinstance(value, str):  # relative to the sweep file
            overrides[key] = str((folder / value).resolve())
        else:
            overrides[key] = value
    return overrides


def _run_id(index: int, width: int, labels: dict[str, str], seed: int) -> str:
    """'0007-output_gain.travel=0.02-output_gain.slew=0.04-seed=3'."""
    setting = "-".join(f"{parameter_label(key)}={text}" for key, text in labels.items())
    setting = _UNSAFE_IN_NAME.sub("_", setting)[:_MAX_SETTING_CHARS]
    return "-".join(part for part in (f"{index:0{width}d}", setting, f"seed={seed}") if part)


def _value_text(value: Any, values: list) -> str:
    """Numbers as numbers, files by their name, per-axis lists joined; anything else by its position."""
    if is_number(value):
        return f"{value:g}"
    if isinstance(value, str):
        return Path(value).stem
    if _is_vector(value):
        return "_".join(f"{v:g}" for v in value)
    return f"#{values.index(value) + 1}"


def _is_vector(value: Any) -> bool:
    return isinstance(value, list) and len(value) == len(AXES) and all(is_number(v) for v in value)


