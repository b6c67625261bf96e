"""Tuning files: what `python -m bwr_twin.tune` tunes, against what, within what budget.

    scene = "../paper_individual_gains.toml"          # the base scene, relative to this file

    [parameters]                                      # a number of the scene; an axis of a per-axis list
    "controller.output_gain.travel" = { low = 0.002, high = 0.2, scale = "log" }
    "controller.input_scale_e" = { low = 10.0, high = 200.0 }    # scale: "linear" (the default)

    [seeds]
    training = [1, 2, 3, 4]                           # every candidate runs these (common random numbers)
    held_out = [101, 102, 103, 104]                   # only the final comparison runs these

    [objective]                                       # weight per metrics.json key, each normalised per
    position_error_rms = 1.0                          # axis by its value at the start and averaged over
    position_error_max = 0.5                          # the axes and the training seeds

    [constraints]
    saturation_fraction = 0.05                        # largest share of time at a drive limit, any axis
    drive_force_rms = [5e4, 2e6, 2e6]                 # N, N m, N m per axis, largest over the seeds
    limits = false                                    # true: metrics.json's limit flags (envelope, end
                                                      # stops, drive ratings) do not make a candidate infeasible

    [budget]
    evaluations = 120                                 # candidates, at most
    wall_time = 3600                                  # s, at most (optional)

    [optimizer]                                       # all optional
    population = 8                                    # candidates a generation (default: CMA-ES's own)
    sigma0 = 0.25                                     # initial step, as a share of each parameter's range
    seed = 1                                          # CMA-ES's random numbers

A parameter must be a number the base scene gives a value (not an integer, a string or a file),
and not one of NOT_TUNABLE (the loop's timing and seed, when a reclaim stops, how the pile is
sampled or drawn); each bound, the others at the start, must make a valid scene. One parameter
is searched by a bounded scalar search (bwr_twin.tune.scalar), two or more by CMA-ES.

Every problem gets one SceneError line naming the file and the key.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bwr_twin.config.scene import Scene, load_scene
from bwr_twin.config.sweep import axis_components, scene_overrides
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import AXES
from bwr_twin.textfile import read_text
from bwr_twin.tomlfile import MISSING, at_dotted, read_toml
from bwr_twin.values import is_integer, is_number

# metrics.json keys an objective may weigh: a per-axis value whose smaller magnitude is better.
OBJECTIVE_METRICS = ("position_error_max", "position_error_rms", "velocity_error_max", "acceleration_error_max",
                     "position_error_final", "drive_force_max", "drive_force_rms", "drive_energy")
_TABLES = {
    "scene": None,
    "parameters": None,
    "seeds": ("training", "held_out"),
    "objective": OBJECTIVE_METRICS,
    "constraints": ("saturation_fraction", "drive_force_rms", "limits"),
    "budget": ("evaluations", "wall_time"),
    "optimizer": ("population", "sigma0", "seed"),
}


@dataclass(frozen=True)
class Parameter:
    """A tuned scene key with its bounds; the optimiser works on [0, 1] (log-spaced if `log`)."""

    key: str
    low: float
    high: float
    log: bool

    def to_unit(self, value: float) -> float:
        if self.log:
            return (math.log(value) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        return (value - self.low) / (self.high - self.low)

    def from_unit(self, u: float) -> float:
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            return math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        return self.low + u * (self.high - self.low)


@dataclass(frozen=True)
class Tuning:
    path: Path
    digest: str  # of the file's text: a DIR tuned by another file is not resumed
    base: Scene
    parameters: tuple[Parameter, ...]
    start: tuple[float, ...]  # the base scene's values of the parameters
    training_seeds: tuple[int, ...]
    held_out_seeds: tuple[int, ...]
    objective: dict[str, float]  # metric -> weight
    max_saturation: float | None
    max_drive_rms: tuple[float, float, float] | None
    limits_allowed: bool
    evaluations: int
    wall_time: float | None  # s
    population: int | None
    sigma0: float
    seed: int

    def scene(self, values: tuple[float, ...] | list[float], seed: int) -> Scene:
        """The base scene with the parameters set to `values` and the disturbance seed."""
        base = self.base.to_dict()
        parameters = {p.key: float(v) for p, v in zip(self.parameters, values)}
        components = axis_components(parameters, base, self.path)
        overrides = scene_overrides(parameters, components, base, self.path.parent)
        overrides["simulation.seed"] = seed
        try:
            return load_scene(self.base.path, overrides)
        except SceneError as exc:
            raise SceneError(f"{self.path}: {exc}") from None


def load_tuning(path: str | Path) -> Tuning:
    """Read and check a tuning file and its base scene."""
    path = Path(path)
    raw = read_toml(path, "tuning")

    def fail(key: str, what: str) -> SceneError:
        return SceneError(f"{path}: '{key}' {what}")

    for table, value in raw.items():
        if table not in _TABLES:
            raise fail(table, f"is not a key of a tuning file (valid: {', '.join(_TABLES)})")
        known = _TABLES[table]
        if known is not None:
            if not isinstance(value, dict):
                raise fail(table, "must be a table")
            for key in value:
                if key not in known:
                    raise fail(f"{table}.{key}", f"is not known (valid here: {', '.join(known)})")
    for table in ("scene", "parameters", "seeds", "objective", "budget"):
        if table not in raw:
            raise SceneError(f"{path}: missing key '{table}'")
    if not isinstance(raw["scene"], str):
        raise fail("scene", f"must be a file path, got {raw['scene']!r}")
    base_path = (path.parent / raw["scene"]).resolve()
    if not base_path.is_file():
        raise fail("scene", f"names a file that does not exist: {base_path}")
    try:
        base = load_scene(base_path)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None

    parameters, start = _parameters(raw["parameters"], base, fail)
    seeds = raw["seeds"]
    training = _seed_list(seeds.get("training"), "seeds.training", fail)
    held_out = _seed_list(seeds.get("held_out"), "seeds.held_out", fail)
    if set(training) & set(held_out):
        raise fail("seeds.held_out", f"shares seeds with 'seeds.training' ({sorted(set(training) & set(held_out))}): "
                   "held-out seeds must be ones the tuner never sees")
    objective = {}
    for metric, weight in raw["objective"].items():
        if not is_number(weight) or weight < 0:
            raise fail(f"objective.{metric}", f"must be a weight >= 0, got {weight!r}")
        if weight:
            objective[metric] = float(weight)
    if not objective:
        raise fail("objective", f"needs a weight > 0 on at least one metric ({', '.join(OBJECTIVE_METRICS)})")
    constraints = raw.get("constraints", {})
    saturation = constraints.get("saturation_fraction")
    if saturation is not None and not (is_number(saturation) and 0 <= saturation <= 1):
        raise fail("constraints.saturation_fraction", f"must be a share from 0 to 1, got {saturation!r}")
    drive_rms = constraints.get("drive_force_rms")
    if drive_rms is not None and not (isinstance(drive_rms, list) and len(drive_rms) == 3
                                      and all(is_number(v) and v > 0 for v in drive_rms)):
        raise fail("constraints.drive_force_rms", f"must be 3 numbers > 0 (N, N m, N m), got {drive_rms!r}")
    limits = constraints.get("limits", False)
    if not isinstance(limits, bool):
        raise fail("constraints.limits", f"must be true or false, got {limits!r}")
    budget = raw["budget"]
    evaluations = budget.get("evaluations")
    if not (is_integer(evaluations) and evaluations >= 1):
        raise fail("budget.evaluations", f"must be an integer >= 1, got {evaluations!r}")
    wall_time = budget.get("wall_time")
    if wall_time is not None and not (is_number(wall_time) and wall_time > 0):
        raise fail("budget.wall_time", f"must be a number of seconds > 0, got {wall_time!r}")
    optimizer = raw.get("optimizer", {})
    population = optimizer.get("population")
    if population is not None and not (is_integer(population) and population >= 2):
        raise fail("optimizer.population", f"must be an integer >= 2, got {population!r}")
    sigma0 = optimizer.get("sigma0", 0.25)
    if not (is_number(sigma0) and 0 < sigma0 <= 1):
        raise fail("optimizer.sigma0", f"must be a share of the ranges in (0, 1], got {sigma0!r}")
    seed = optimizer.get("seed", 1)
    if not (is_integer(seed) and seed >= 1):
        raise fail("optimizer.seed", f"must be an integer >= 1, got {seed!r}")
    tuning = Tuning(
        path=path, digest=hashlib.sha256(read_text(path).encode()).hexdigest(), base=base,
        parameters=parameters, start=start, training_seeds=training, held_out_seeds=held_out,
        objective=objective, max_saturation=saturation, max_drive_rms=tuple(drive_rms) if drive_rms else None,
        limits_allowed=limits, evaluations=evaluations, wall_time=wall_time, population=population,
        sigma0=float(sigma0), seed=seed,
    )
    _check_bounds(parameters, tuning, fail)
    return tuning


def _parameters(table: Any, base: Scene, fail) -> tuple[tuple[Parameter, ...], tuple[float, ...]]:
    if not table:
        raise fail("parameters", "needs at least one scene key to tune")
    base_dict = base.to_dict()
    components = axis_components(dict.fromkeys(table, None), base_dict, base.path)
    parameters, start = [], []
    for key, spec in table.items():
        where = f"parameters.{key}"
        if not isinstance(spec, dict) or not {"low", "high"} <= set(spec) <= {"low", "high", "scale"}:
            raise fail(where, f"must be {{ low, high[, scale] }}, got {spec!r}")
        low, high, scale = spec["low"], spec["high"], spec.get("scale", "linear")
        if not (is_number(low) and is_number(high) and low < high):
            raise fail(where, f"needs numbers low < high, got low = {low!r}, high = {high!r}")
        if scale not in ("linear", "log"):
            raise fail(f"{where}.scale", f"must be \"linear\" or \"log\", got {scale!r}")
        if scale == "log" and low <= 0:
            raise fail(where, f"a log scale needs low > 0, got {low}")
        value = _tunable_value(key, components, base_dict, where, fail)
        if not low <= value <= high:
            raise fail(where, f"starts at the base scene's {value:g}, outside [{low:g}, {high:g}]")
        parameters.append(Parameter(key, float(low), float(high), scale == "log"))
        start.append(float(value))
    return tuple(parameters), tuple(start)


# Scene keys that are numbers but no setting to tune: what they change is not the controller,
# the plant or the world, or it changes the run that the candidates are compared on.
NOT_TUNABLE = {
    "simulation": "sets the loop's timing and the seed, not the controller or the plant",
    "reclaim.stop": "decides when a run ends: the candidates would be scored on different runs",
    "stockpile.grid_spacing": "is how finely the pile is sampled, not the pile",
    "stockpile.colour": "only changes how the pile is drawn",
    "stockpile.base_depth": "only changes how the pile is drawn",
}


def _tunable_value(key: str, components: dict, base: dict, where: str, fail) -> float:
    """The base scene's value of a tuned key, or a one-line refusal saying why it cannot be tuned."""
    for prefix, why in NOT_TUNABLE.items():
        if key == prefix or key.startswith(prefix + "."):
            raise fail(where, f"cannot be tuned: '{prefix}' {why}")
    if key in components:
        parent, axis = components[key]
        return float(at_dotted(base, parent)[axis])
    value = at_dotted(base, key)
    parent, _, last = key.rpartition(".")
    if value is MISSING and _is_axes(at_dotted(base, parent)):
        raise fail(where, f"names no axis of the per-axis list '{parent}': tune {_axes_of(parent)}")
    if value is MISSING:
        raise fail(where, f"names no key of the base scene; its numbers that can be tuned: "
                   f"{', '.join(tunable_keys(base))}")
    if value is None:
        raise fail(where, "has no value in the base scene (the model's is used); give it one there to tune it")
    if _is_axes(value):
        raise fail(where, f"is a per-axis list: tune its axes one by one, {_axes_of(key)}")
    if isinstance(value, float) and is_number(value):
        return value
    kind = "an integer setting" if is_integer(value) else f"not a number ({value!r})"
    raise fail(where, f"is {kind} in the base scene; tune a number, or one axis of a per-axis list")


def tunable_keys(base: dict) -> list[str]:
    """The dotted keys of the base scene's numbers (scene.to_dict()) that a tuning may name."""
    keys = []

    def walk(table: dict, prefix: str) -> None:
        for name, value in table.items():
            key = f"{prefix}{name}"
            if any(key == p or key.startswith(p + ".") for p in NOT_TUNABLE):
                continue
            if isinstance(value, dict):
                walk(value, key + ".")
            elif _is_axes(value):
                keys.extend(f"{key}.{axis}" for axis in AXES)
            elif isinstance(value, float):
                keys.append(key)

    walk({k: v for k, v in base.items() if k not in ("path", "trajectory")}, "")
    return keys


def _is_axes(value: Any) -> bool:
    return isinstance(value, list) and len(value) == len(AXES) and all(isinstance(v, float) for v in value)


def _axes_of(key: str) -> str:
    return ", ".join(f"{key}.{axis}" for axis in AXES)


def _check_bounds(parameters: tuple[Parameter, ...], tuning: Tuning, fail) -> None:
    """Each parameter at its low and at its high bound, the others at the start, must make a valid
    scene: a rule broken there is refused now, not after generations of work."""
    for i, parameter in enumerate(parameters):
        for bound in (parameter.low, parameter.high):
            values = list(tuning.start)
            values[i] = bound
            try:
                tuning.scene(values, tuning.base.simulation.seed)
            except SceneError as exc:
                why = str(exc).removeprefix(f"{tuning.path}: ").removeprefix(f"{tuning.base.path}: ")
                raise fail(f"parameters.{parameter.key}", f"at its bound {bound:g} makes a scene that breaks "
                           f"a rule ({why}); narrow the bounds") from None


def _seed_list(value: Any, key: str, fail) -> tuple[int, ...]:
    if not (isinstance(value, list) and value and all(is_integer(v) and v >= 0 for v in value)
            and len(set(value)) == len(value)):
        raise fail(key, f"must be a list of distinct integers >= 0, got {value!r}")
    return tuple(value)
