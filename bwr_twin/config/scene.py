"""Scenes: TOML files in scenes/ loaded into typed, validated, frozen configuration.

A scene names the machine, the reclaim path, the physics and control rates, the imperfect world
(encoders, disturbances, unmodelled plant effects) and the controller settings. Every key is
checked against the dataclasses below; a bad file raises SceneError with one line naming the
file, the key and the rule it broke; a physical input beyond the range of real materials, air and
machines is refused the same way (bwr_twin.config.bounds). `overrides` (dotted keys, as a sweep or
the command line gives them) are applied before validation, so they are checked exactly like the file.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from bwr_twin.config.bounds import check_bounds
from bwr_twin.config.faults import FaultSection, check_fault_count, check_faults
from bwr_twin.config.plugins import (
    CONTROLLERS,
    INTERLOCKS,
    RATE_CONTROLS,
    controller_class,
    interlock_class,
    is_file_reference,
    rate_control_class,
)
from bwr_twin.errors import SceneError
from bwr_twin.textfile import read_text, version
from bwr_twin.values import is_integer, is_number

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ViaPoint:
    t: float  # s
    p: Vec3  # m, in the path's frame


@dataclass(frozen=True)
class MachineSection:
    mjcf: Path  # the plant
    controller_mjcf: Path | None = None  # what the controller believes; None: the plant's file


@dataclass(frozen=True)
class PathSection:
    frame: Literal["paper", "world"]
    via_points: tuple[ViaPoint, ...]


@dataclass(frozen=True)
class SimulationSection:
    timestep: float  # s, physics
    control_period: float  # s, controller and disturbance update
    record_period: float  # s, rows of timeseries.csv (metrics use every control period)
    seed: int


@dataclass(frozen=True)
class EncoderSection:
    resolution: Vec3  # m, rad, rad
    velocity_source: Literal["true", "encoder"] = "true"  # the plant's joint velocity, or estimated
    velocity_filter: float = 0.05  # s, time constant of the encoder velocity estimate


@dataclass(frozen=True)
class DisturbanceSection:
    amplitude: Vec3  # N, N m, N m; uniform in [-a, a]
    hold_time: float  # s


@dataclass(frozen=True)
class ControllerSection:
    """`[controller]`: `type` names the controller (bwr_twin.config.plugins), the other keys
    are its settings, an instance of that controller's `Settings` dataclass."""

    type: str
    settings: Any

    @property
    def files(self) -> tuple[Path, ...]:
        """The files the controller reads: its Python file, if it is an engineer's, and its settings' files."""
        source = (Path(self.type.rpartition(":")[0]),) if ":" in self.type else ()
        return source + tuple(v for v in self.to_dict().values() if isinstance(v, Path))

    def to_dict(self) -> dict[str, Any]:
        """{"type": ..., setting: value, ...}: the [controller] table as the scene file has it."""
        settings = {f.name: getattr(self.settings, f.name) for f in dataclasses.fields(self.settings)}
        return {"type": self.type, **settings}

    def label(self) -> str:
        """'fuzzy_model, output_gain 0.01/0.04/0.06': the type and its per-axis settings, for titles."""
        name = Path(self.type).name if ":" in self.type else self.type
        per_axis = [f"{k} {'/'.join(f'{x:g}' for x in v)}" for k, v in self.to_dict().items()
                    if isinstance(v, tuple) and all(is_number(x) for x in v)]
        return ", ".join([name, *per_axis])

    def __reduce__(self) -> tuple:
        # Rebuilt from plain data: a worker process imports an engineer's file itself.
        return (_controller_section, (self.type, self.to_dict()))


def _controller_section(type_name: str, values: dict[str, Any]) -> ControllerSection:
    values = {k: v for k, v in values.items() if k != "type"}
    return ControllerSection(type_name, controller_class(type_name).Settings(**values))


@dataclass(frozen=True)
class Payload:
    body: str  # the MJCF body that carries it
    mass: float  # kg
    pos: Vec3  # m, in that body's frame


@dataclass(frozen=True)
class PlantSection:
    """Unmodelled effects: they act on the plant only, never on the controller's belief."""

    frictionloss: Vec3 | None = None  # Coulomb friction, N and N m; None keeps the MJCF's
    wind_speed: float = 0.0  # m/s, mean, blowing towards wind_direction
    wind_direction: float = 90.0  # deg from world +X towards +Y
    gust_amplitude: float = 0.0  # m/s, uniform in [-a, a] around the mean
    gust_hold_time: float = 5.0  # s, how long one gust lasts
    air_density: float = 1.204  # kg/m^3, dry air at 20 degC
    payload: tuple[Payload, ...] = ()  # point masses the plant carries and its MJCF does not show


@dataclass(frozen=True)
class WindrowSection:
    """A windrow: a flat crest `length` x `crest_width` at `height`, its flanks and its ends
    falling at the angle of repose to the ground."""

    length: float  # m, of the crest, along the rail
    crest_width: float  # m
    height: float  # m
    angle_of_repose: float  # deg
    centre: tuple[float, float]  # m, world X and Y of the crest's centre


@dataclass(frozen=True)
class StockpileSection:
    """The pile the wheel digs: a windrow, or a surveyed surface read from a file."""

    bulk_density: float  # kg/m^3, of the stockpiled (loose) material
    grid_spacing: float = 0.25  # m between height samples: a 0.8 m cut spans three
    windrow: WindrowSection | None = None
    surface_file: Path | None = None  # .npz with x, y (grid lines, m) and z (heights, m), or .csv x,y,z points
    # deg: the faces the wheel cuts slump to it, volume kept (bwr_twin.pile.cutting); None: they stand
    angle_of_repose: float | None = None
    # How the pile's hfield is drawn in the MuJoCo world (bwr_twin.model.spec), nothing else:
    colour: tuple[float, float, float, float] = (0.55, 0.27, 0.15, 1.0)  # rgba: iron ore's red-brown
    base_depth: float = 1.0  # m of the hfield's base box below the yard floor, as MuJoCo draws it


@dataclass(frozen=True)
class DiggingSection:
    """The digging load: the wheel's cutting power P = cutting_energy x Q + idle_power, Q the
    volume it digs a second; the cutting force at the rim is that power over the rim speed."""

    cutting_energy: float  # J/m^3 of material dug
    idle_power: float = 0.0  # W, the wheel drive turning empty
    lateral_ratio: float = 0.4  # force against the slewing, as a share of the tangential force


@dataclass(frozen=True)
class SensingSection:
    """`[sensing]`: the automation's own senses (docs/sensing.md)."""

    # The machine's 2D laser scanners: None scans with them if the machine has any and the scene
    # a stockpile; false leaves them off (for comparison); true asks for them.
    scanners: bool | None = None
    # The pile a bench reclaim is planned on: "scanned", the pile its runs know from their scans
    # after the [reclaim.survey] pass (None: when they scan), or "exact", the true pile.
    pile_model: Literal["scanned", "exact"] | None = None
    # What the rate loop reads: "measured", the machine's belt scale and wheel current with their
    # delay and noise (None: when its MJCF describes them), or "exact", the true rate and power.
    rate_signals: Literal["measured", "exact"] | None = None


@dataclass(frozen=True)
class RateControlSection:
    """`[reclaim.rate_control]`: how the slew speed is trimmed to hold the target rate.

    `type` "open_loop" follows the speed law alone; "belt_scale" trims it from the measured
    reclaim rate, "wheel_power" from the wheel drive's power (the industry's proxy; it needs
    [digging]), "power_and_scale" from the power as the belt scale calibrates it; or an
    engineer's class, "my_rate.py:MyRateControl" (bwr_twin.control.rate).
    The trim is a PI on the relative rate error: 1 + gain (e + integral(e) / integral_time),
    within trim_limits, the measurement smoothed first over filter_time (a bucket wheel's rate
    pulses with every bucket).
    """

    type: str = RATE_CONTROLS.default
    gain: float = 0.5  # trim per unit of relative rate error
    integral_time: float = 4.0  # s
    filter_time: float = 1.0  # s, first-order low-pass on the measured rate
    trim_limits: tuple[float, float] = (0.5, 2.0)  # the slew speed within these multiples of the law's
    # "power_and_scale": the memory of the belt scale's correction to the power's calibration
    calibration_time: float = 300.0  # s
    # J/m^3 the automation assumes to turn the wheel's power into a rate; None: [digging]'s own
    cutting_energy: float | None = None


@dataclass(frozen=True)
class InterlockSection:
    """`[interlock]`: the anti-collision interlock (docs/anticollision.md). `type` "zones", the
    built-in: from each collision shape's clearance to the pile the automation knows, less the
    distance the machine would cover before it stands (its speed for `reaction` s, then braking
    at `deceleration`), it warns within `warn` m, slows the path to `slow_share` of its speed
    within `slow` m and stops it within `stop` m, held until the run ends; it leaves a warning or
    a slowdown once the predicted clearance is `hysteresis` m beyond the zone's edge. With
    `encoder_check` it quick-stops the drives where an encoder's motion over `encoder_window` s
    parts from its drive's own speed feedback by more than `encoder_tolerance` m at the shapes. Or an
    engineer's class, "my_interlock.py:MyInterlock" (bwr_twin.collision.interlock), given these
    numbers too."""

    warn: float  # m of predicted clearance
    slow: float  # m
    stop: float  # m
    reaction: float = 0.5  # s from a decision to the drives acting on it
    deceleration: float = 0.05  # m/s^2 the drives brake the shapes at
    slow_share: float = 0.3  # of the path's speed, in the slow zone
    hysteresis: float = 0.5  # m beyond a zone's edge the predicted clearance must reach to leave it
    encoder_check: bool = True  # check the encoders against the drives' speed feedback
    encoder_tolerance: float = 0.2  # m at the shapes the two may part by
    encoder_window: float = 1.0  # s over which their motions are compared
    type: str = INTERLOCKS.default


@dataclass(frozen=True)
class StopSection:
    """`[reclaim.stop]`: when the reclaim ends; exactly one key."""

    benches: int | None = None  # after this many benches
    tonnes: float | None = None  # t, once the belt has carried this much
    time: float | None = None  # s


@dataclass(frozen=True)
class SurveySection:
    """`[reclaim.survey]`: a pass with the boom's scanners before the plan is made, as automatic
    reclaimers survey their pile: the machine moves from 'start' through the waypoints, each
    reached at rest by the quickest smooth move its rated speeds and the reclaim's
    accelerations allow, and the plan starts where the last one leaves it."""

    waypoints: tuple[Vec3, ...]  # travel m, slew deg, luff deg


@dataclass(frozen=True)
class ReclaimSection:
    """`[reclaim]`: bench reclaiming planned from the pile (bwr_twin.planning.bench), instead
    of [path]'s via points."""

    target_rate: float  # t/h
    bench_height: float  # m, at most 0.6 x the wheel's diameter
    cut_depth: float  # m the travel advances between slew passes
    bench_length: float  # m of travel a bench advances before the boom steps down
    slew_limits: tuple[float, float]  # deg, the slew across the face stays within them
    start: Vec3  # where the machine stands at t = 0: travel m, slew deg, luff deg
    acceleration: Vec3  # m/s^2, deg/s^2, deg/s^2: the most the references ask of each axis
    stop: StopSection
    speed_law: Literal["cosine", "constant"] = "cosine"  # slew speed ~ 1/cos(slew), or constant
    cap_angle: float = 70.0  # deg: beyond it the cosine law holds its speed
    rate_control: RateControlSection = field(default_factory=RateControlSection)
    survey: SurveySection | None = None


@dataclass(frozen=True)
class GradeSection:
    """`[stacking.grade]`: the grade of the stream arriving to be stacked (a number such as
    Fe %, bwr_twin.stockpile.grade): an AR(1) of `mean`, `sd` and `correlation_time` drawn from
    each run's seed, or a recorded CSV `file` of t (s), grade rows."""

    mean: float | None = None
    sd: float = 0.0
    correlation_time: float = 0.0  # s; 0: each deposit's grade independent of the last
    file: Path | None = None
    interpolation: Literal["step", "linear"] = "step"  # between a recorded file's rows
    name: str = "grade"  # what the grade is, for labels: "Fe %", "ash %"
    band: tuple[float, float] | None = None  # the grade the pile's customer accepts, for metrics


@dataclass(frozen=True)
class StackingSection:
    """`[stacking]`: the machine stacks a pile instead of following a path or reclaiming one
    (docs/blending.md). It discharges `rate` t/h at its CP (a stacker's discharge point) until
    `tonnes` are laid, on its `pattern` along the pile's axis, from `axis_x[0]` to `axis_x[1]` at
    `axis_y` (world m): "chevron", passes to and fro along the axis, one layer a pass; "windrow",
    rows side by side, each layer's in the valleys of the one below; "cone_shell", cones standing
    one against the next; "strata", horizontal layers of equal tonnes, each in rows `row_spacing`
    apart across the pile. `layers` counts the chevron's passes, the windrow's bottom rows, the
    cones or the strata. The discharge point is held `drop` m above the crest the pile's target
    section has reached, luffed up between passes. The material falls and slumps to its angle
    of repose every `deposit_period` s."""

    rate: float  # t/h
    tonnes: float  # t to stack
    axis_x: tuple[float, float]  # m: where the pile's axis starts and ends, along the rail
    axis_y: float  # m: the axis's distance beside the rail's
    layers: int  # chevron passes, windrow bottom rows, cones or strata (docs/blending.md)
    bulk_density: float  # kg/m^3 of the stacked (loose) material
    angle_of_repose: float  # deg
    grade: GradeSection
    pattern: Literal["chevron", "windrow", "cone_shell", "strata"] = "chevron"
    row_spacing: float = 5.0  # m between the rows of a stratum ("strata" only)
    drop: float = 2.0  # m from the discharge point down to the crest
    acceleration: float = 0.05  # m/s^2 of the travel as a pass starts and ends
    grid_spacing: float = 0.5  # m between the pile's height samples
    deposit_period: float = 1.0  # s between deposits: laid and slumped this often
    max_layers: int = 64  # a column's layers (bwr_twin.stockpile.layers)


@dataclass(frozen=True)
class ScheduleStep:
    t: float  # s
    q: Vec3  # travel m, slew deg, luff deg


@dataclass(frozen=True)
class NeighbourSection:
    """`[neighbour]`: a second machine on the same rail, from its own MJCF, simulated in the same
    world (docs/anticollision.md). It follows its `schedule`: where it stands at each time, at
    rest there, one cubic between (the path's law); before the first time and after the last it
    stands still. Its drives hold the schedule with a PD on its own inertia at its start,
    critically damped at `bandwidth`, gravity and bias compensated, within their force limits."""

    mjcf: Path
    schedule: tuple[ScheduleStep, ...]
    bandwidth: float = 0.5  # rad/s of the drives' hold on the schedule
    report_delay: float = 0.5  # s: the automation hears its position this late (its radio link)


@dataclass(frozen=True)
class Scene:
    path: Path  # the scene file, for messages
    machine: MachineSection
    simulation: SimulationSection
    encoders: EncoderSection
    disturbance: DisturbanceSection
    controller: ControllerSection
    trajectory: PathSection | None = None  # via points, or
    reclaim: ReclaimSection | None = None  # a bench reclaim planned from the stockpile, or [stacking]
    plant: PlantSection = field(default_factory=PlantSection)
    stockpile: StockpileSection | None = None
    digging: DiggingSection | None = None
    sensing: SensingSection = field(default_factory=SensingSection)
    faults: tuple[FaultSection, ...] = ()  # [[faults]]: what fails, when, for how long (docs/sensing.md)
    interlock: InterlockSection | None = None  # the anti-collision interlock (docs/anticollision.md)
    neighbour: NeighbourSection | None = None  # a second machine on the rail (docs/anticollision.md)
    stacking: StackingSection | None = None  # the machine stacks a pile (docs/blending.md)

    @property
    def controller_mjcf(self) -> Path:
        return self.machine.controller_mjcf or self.machine.mjcf

    @property
    def input_files(self) -> tuple[Path, ...]:
        """The files this scene reads: nothing the twin writes may replace them."""
        pile = (self.stockpile.surface_file,) if self.stockpile and self.stockpile.surface_file else ()
        if self.stacking is not None and self.stacking.grade.file is not None:
            pile += (self.stacking.grade.file,)
        classes = (self.reclaim.rate_control.type if self.reclaim else "",
                   self.interlock.type if self.interlock else "")
        class_files = tuple(Path(name.rpartition(":")[0]) for name in classes if ":" in name)
        neighbour = (self.neighbour.mjcf,) if self.neighbour else ()
        return (self.path, self.machine.mjcf, self.controller_mjcf, *self.controller.files, *pile, *class_files,
                *neighbour)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (paths as strings), as written next to a run's results."""
        tables = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        tables["controller"] = self.controller.to_dict()
        return _plain({k: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v for k, v in tables.items()})


# TOML table name of each Scene field ("path" is a reserved word of the scene itself).
_TABLES = {"trajectory": "path"}


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
    raw = copy.deepcopy(_read_raw_once(path, version(path)))
    for key, value in (overrides or {}).items():
        if _is_path_key(key):
            value = _resolve_paths(value, Path.cwd())
        elif key in CLASS_KEYS:
            value = _resolve_class_reference(value, Path.cwd())
        _set_dotted(raw, key, value, path)
        _drop_alternatives(raw, key)
    scene = _build(Scene, {"path": str(path), **_rename_tables(raw)}, path, "")
    _check_rules(scene)
    return scene


@functools.lru_cache(maxsize=32)
def _read_raw_once(path: Path, stamp: tuple) -> dict:
    """_read_raw, once per version of a file: a sweep loads one base scene for every run."""
    return _read_raw(path, ())


def _read_raw(path: Path, extended_by: tuple[Path, ...]) -> dict:
    """The file's tables, paths made absolute, merged over the scene it extends."""
    if not path.is_file():
        by = f" (extended by {extended_by[-1]})" if extended_by else ""
        raise SceneError(f"{path}: scene file not found{by}")
    try:
        text = read_text(path)
        check_fault_count(path, text)  # before a table is parsed
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: malformed TOML: {exc}") from None
    except UnicodeDecodeError:
        raise SceneError(f"{path}: not a text file") from None
    base = raw.pop("extends", None)
    replace = raw.pop("replace", [])
    raw = _resolve_paths(raw, path.parent)
    if base is None:
        if replace:
            raise SceneError(f"{path}: 'replace' names tables of the scene it extends, but it has no 'extends'")
        return raw
    if not isinstance(base, str):
        raise SceneError(f"{path}: 'extends' must be a file path or a shipped scene's name, got {base!r}")
    if not (isinstance(replace, list) and all(isinstance(t, str) and t for t in replace)):
        raise SceneError(f"{path}: 'replace' must be a list of table names, e.g. [\"digging\"], got {replace!r}")
    base_path = _extended(path, base)
    chain = extended_by + (path.resolve(),)
    if base_path in chain:
        raise SceneError(f"{path}: 'extends' makes a cycle through {base_path.name}")
    base_raw = _read_raw(base_path, chain)
    merged = _merged(base_raw, raw)
    named = raw.get("controller", {}).get("type") if isinstance(raw.get("controller"), dict) else None
    if named is not None and named != _controller_type(base_raw):
        merged["controller"] = raw["controller"]  # another controller: none of the base's settings
    for dotted, keys in ALTERNATIVES.items():
        given, inherited = _table(raw, dotted), _table(merged, dotted)
        if given is not None and inherited is not None and any(k in given for k in keys):
            for key in keys:
                if key not in given:
                    inherited.pop(key, None)  # one alternative replaces the base's other
    for dotted in replace:
        *parents, name = dotted.split(".")
        node, own = merged, _table(raw, ".".join(parents)) if parents else raw
        for parent in parents:
            node = node.get(parent) if isinstance(node, dict) else None
        if isinstance(node, dict) and name in node:
            node.pop(name)  # this file's table, or none: nothing of the base's
            if own is not None and name in own:
                node[name] = own[name]
    return merged


# Keys of a table that exclude each other: a scene that extends another and gives one of them
# replaces whichever of them its base gave ("" is the top level).
ALTERNATIVES = {
    "": ("path", "reclaim", "stacking"),
    "stockpile": ("windrow", "surface_file"),
    "reclaim.stop": ("benches", "tonnes", "time"),
}


def _drop_alternatives(raw: dict, dotted: str) -> None:
    """An override of one of ALTERNATIVES' keys replaces the others, as an extending file's does."""
    parent, _, name = dotted.rpartition(".")
    table = _table(raw, parent)
    if table is not None and name in ALTERNATIVES.get(parent, ()):
        for other in ALTERNATIVES[parent]:
            if other != name:
                table.pop(other, None)


def _table(raw: dict, dotted: str) -> dict | None:
    node: Any = raw
    for name in filter(None, dotted.split(".")):
        node = node.get(name) if isinstance(node, dict) else None
    return node if isinstance(node, dict) else None


def _extended(path: Path, base: str) -> Path:
    """The scene file `extends` names: relative to the scene's folder, or else a shipped scene's
    name, as on the command line ("heavy_reclaim"); relative paths win."""
    from bwr_twin.shipped import SCENES

    local = (path.parent / base).resolve()
    if local.is_file():
        return local
    for shipped in (SCENES / base, SCENES / f"{base}.toml"):
        if shipped.is_file():
            return shipped.resolve()
    raise SceneError(f"{path}: 'extends' names {base!r}, neither a file beside it ({local}) nor a shipped "
                     "scene (python -m bwr_twin.run lists them for a name it does not know)")


def _controller_type(raw: dict) -> str:
    """The controller type a raw scene names, or the default one."""
    table = raw.get("controller")
    return table.get("type", CONTROLLERS.default) if isinstance(table, dict) else CONTROLLERS.default


def _merged(base: dict, over: dict) -> dict:
    """`over` laid over `base`: tables merge key by key, anything else replaces."""
    out = dict(base)
    for key, value in over.items():
        out[key] = _merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _rename_tables(raw: dict) -> dict:
    out = dict(raw)
    for attr, table in _TABLES.items():
        if table in out:
            out[attr] = out.pop(table)
    return out


# Keys whose values are files, relative to the scene file that gives them: these, any key that
# ends in "_file", and the file part of a controller type "my_controller.py:MyController".
PATH_KEYS = frozenset({"mjcf", "controller_mjcf", "rule_base"})
# Keys that name a class, built in or "file.py:ClassName" relative to the scene file.
CLASS_KEYS = (CONTROLLERS.key, RATE_CONTROLS.key, INTERLOCKS.key)


def _is_path_key(dotted: str) -> bool:
    key = dotted.rsplit(".", 1)[-1]
    return key in PATH_KEYS or key.endswith("_file")


def _resolve_class_reference(value: Any, base: Path) -> Any:
    if not (isinstance(value, str) and is_file_reference(value)):
        return value
    file, _, name = value.rpartition(":")
    return f"{(base / file).resolve()}:{name}"


def _resolve_paths(raw: Any, base: Path) -> Any:
    """Make the path-valued keys absolute, relative to `base`."""
    if isinstance(raw, str):
        return str((base / raw).resolve())
    if not isinstance(raw, dict):
        return raw
    resolved = {
        k: (
            str((base / v).resolve())
            if _is_path_key(k) and isinstance(v, str)
            else _resolve_paths(v, base)
            if isinstance(v, dict)
            else v
        )
        for k, v in raw.items()
    }
    for dotted in CLASS_KEYS:
        *tables, key = dotted.split(".")
        node = resolved
        for table in tables:
            node = node.get(table) if isinstance(node, dict) else None
        if isinstance(node, dict) and key in node:
            node[key] = _resolve_class_reference(node[key], base)
    return resolved


def _set_dotted(raw: dict, dotted: str, value: Any, path: Path) -> None:
    *tables, key = dotted.split(".")
    node = raw
    for table in tables:
        node = node.setdefault(table, {})
        if not isinstance(node, dict):
            raise SceneError(f"{path}: override '{dotted}': '{table}' is not a table")
    node[key] = copy.deepcopy(value)


# Keys that have moved: old dotted key -> new dotted key.
MOVED_KEYS = {
    "controller.velocity_source": "encoders.velocity_source",
    "controller.velocity_filter": "encoders.velocity_filter",
}


def _build(cls: type, table: Any, path: Path, where: str) -> Any:
    """Build dataclass `cls` from a TOML table, checking keys and types."""
    if not isinstance(table, dict):
        raise SceneError(f"{path}: [{where}] must be a table")
    for key in table:
        if _join(where, key) in MOVED_KEYS:
            raise SceneError(f"{path}: '{_join(where, key)}' has moved: write it as '{MOVED_KEYS[_join(where, key)]}'")
    hints = _type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    shown = {_TABLES.get(n, n): n for n in fields}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        key = _TABLES.get(unknown[0], unknown[0])
        valid = ", ".join(sorted(shown))
        raise SceneError(f"{path}: unknown key '{_join(where, key)}' (valid here: {valid})")
    kwargs = {}
    for name, f in fields.items():
        key = _join(where, _TABLES.get(name, name))
        if name not in table:
            no_default = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
            if no_default:
                raise SceneError(f"{path}: missing key '{key}'")
            continue
        kwargs[name] = _convert(hints[name], table[name], path, key)
    return cls(**kwargs)


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)  # evaluates the annotations' text: slow, and never changes


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _convert(hint: Any, value: Any, path: Path, key: str) -> Any:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _convert(inner, value, path, key)
    if hint is ControllerSection:
        return _build_controller(value, path, key)
    if dataclasses.is_dataclass(hint):
        return _build(hint, value, path, key)
    if origin is Literal:
        if value not in args:
            raise SceneError(f"{path}: '{key}' must be one of {list(args)}, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise SceneError(f"{path}: '{key}' must be a list, got {type(value).__name__}")
        if args[-1] is Ellipsis:
            return tuple(_convert(args[0], v, path, f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            meaning = " (travel, slew, luff)" if len(args) == 3 else ""
            raise SceneError(f"{path}: '{key}' must hold {len(args)} values{meaning}, got {len(value)}")
        return tuple(_convert(a, v, path, f"{key}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if hint is float:
        if not is_number(value):
            raise SceneError(f"{path}: '{key}' must be a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if not is_integer(value):
            raise SceneError(f"{path}: '{key}' must be an integer, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise SceneError(f"{path}: '{key}' must be true or false, got {value!r}")
        return value
    if hint is Path:
        if not isinstance(value, str):
            raise SceneError(f"{path}: '{key}' must be a file path, got {value!r}")
        return Path(value)
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(f"{path}: '{key}' must be a string, got {value!r}")
        return value
    raise TypeError(f"unsupported scene field type {hint}")  # a bug here, not in the file


def _build_controller(table: Any, path: Path, where: str) -> ControllerSection:
    """[controller]: its `type` picks the Settings dataclass that the other keys must fill."""
    from bwr_twin.control.interface import SettingsError

    if not isinstance(table, dict):
        raise SceneError(f"{path}: [{where}] must be a table")
    type_name = table.get("type", CONTROLLERS.default)
    if not isinstance(type_name, str):
        raise SceneError(f"{path}: '{where}.type' must be a string, got {type_name!r}")
    try:
        cls = controller_class(type_name)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None
    settings = _build(cls.Settings, {k: v for k, v in table.items() if k != "type"}, path, where)
    try:
        getattr(settings, "validate", lambda: None)()
    except SettingsError as exc:
        raise SceneError(f"{path}: '{where}.{exc.key}' {exc.message}") from None
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - an engineer's validate(): say whose
        raise SceneError(f"{path}: controller {type_name}: {cls.__name__}.Settings.validate() raised "
                         f"{type(exc).__name__}" + (f": {exc}" if str(exc) else "")) from None
    return ControllerSection(type_name, settings)


def _check_rules(scene: Scene) -> None:
    """Rules that types alone do not express."""
    p = scene.path
    sim = scene.simulation

    def positive(key: str, value: float) -> None:
        if not value > 0:
            raise SceneError(f"{p}: '{key}' must be > 0, got {value}")

    if sim.seed < 0:
        raise SceneError(f"{p}: 'simulation.seed' must be >= 0, got {sim.seed}")
    positive("simulation.timestep", sim.timestep)
    positive("simulation.control_period", sim.control_period)
    positive("simulation.record_period", sim.record_period)
    positive("disturbance.hold_time", scene.disturbance.hold_time)
    positive("encoders.velocity_filter", scene.encoders.velocity_filter)
    positive("plant.gust_hold_time", scene.plant.gust_hold_time)
    for axis, value in zip(("travel", "slew", "luff"), scene.encoders.resolution):
        positive(f"encoders.resolution ({axis})", value)
    for key, vec in (("disturbance.amplitude", scene.disturbance.amplitude), ("plant.frictionloss", scene.plant.frictionloss)):
        if vec is not None and min(vec) < 0:
            raise SceneError(f"{p}: '{key}' must be >= 0 on every axis, got {list(vec)}")
    for i, payload in enumerate(scene.plant.payload):
        if not payload.mass > 0:
            raise SceneError(f"{p}: 'plant.payload[{i}].mass' must be > 0, got {payload.mass}")
    for key, value in (("plant.gust_amplitude", scene.plant.gust_amplitude), ("plant.wind_speed", scene.plant.wind_speed), ("plant.air_density", scene.plant.air_density)):
        if value < 0:
            raise SceneError(f"{p}: '{key}' must be >= 0, got {value}")
    for period, unit in (("control_period", "timestep"), ("record_period", "control_period")):
        ratio = getattr(sim, period) / getattr(sim, unit)
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise SceneError(
                f"{p}: 'simulation.{period}' ({getattr(sim, period)} s) must be a whole multiple of "
                f"'simulation.{unit}' ({getattr(sim, unit)} s)"
            )
    plans = [name for name, given in (("[path]", scene.trajectory), ("[reclaim]", scene.reclaim),
                                      ("[stacking]", scene.stacking)) if given is not None]
    if len(plans) != 1:
        raise SceneError(f"{p}: a scene needs one of a [path] of via points, a [reclaim] or a [stacking], "
                         f"got {' and '.join(plans) if plans else 'none'}")
    if scene.trajectory is not None:
        _check_path(scene)
    _check_stockpile(scene)
    if scene.reclaim is not None:
        _check_reclaim(scene)
    if scene.stacking is not None:
        _check_stacking(scene)
    _check_sensing(scene)
    _check_interlock(scene)
    _check_neighbour(scene)
    runs_until = scene.trajectory.via_points[-1].t if scene.trajectory is not None else None
    check_faults(p, scene.faults, runs_until)
    files = {"machine.mjcf": scene.machine.mjcf, "machine.controller_mjcf": scene.machine.controller_mjcf}
    files |= {f"controller.{k}": v for k, v in scene.controller.to_dict().items() if isinstance(v, Path)}
    for key, file in files.items():
        if file is not None and not file.is_file():
            raise SceneError(f"{p}: '{key}' names a file that does not exist: {file}")
    check_bounds(scene)  # physics that cannot be: each physical input within a sane range, with its source


def _check_path(scene: Scene) -> None:
    p, via = scene.path, scene.trajectory.via_points
    if len(via) < 2:
        raise SceneError(f"{p}: 'path.via_points' needs at least 2 via points, got {len(via)}")
    for i in range(1, len(via)):
        if not via[i].t > via[i - 1].t:
            raise SceneError(
                f"{p}: via point {i + 1} (t = {via[i].t} s) must come after via point {i} "
                f"(t = {via[i - 1].t} s): times must increase"
            )


def _check_reclaim(scene: Scene) -> None:
    """The rules of [reclaim] that need no machine; the planner checks the rest against it."""
    p, r = scene.path, scene.reclaim
    if scene.stockpile is None:
        raise SceneError(f"{p}: [reclaim] needs a [stockpile] to reclaim")
    for key in ("target_rate", "bench_height", "cut_depth", "bench_length"):
        if not getattr(r, key) > 0:
            raise SceneError(f"{p}: 'reclaim.{key}' must be > 0, got {getattr(r, key)}")
    if r.bench_length < r.cut_depth:
        raise SceneError(f"{p}: 'reclaim.bench_length' ({r.bench_length} m) must be at least one "
                         f"'reclaim.cut_depth' ({r.cut_depth} m)")
    for axis, value in zip(("travel", "slew", "luff"), r.acceleration):
        if not value > 0:
            raise SceneError(f"{p}: 'reclaim.acceleration' ({axis}) must be > 0, got {value}")
    low, high = r.slew_limits
    if not low < high:
        raise SceneError(f"{p}: 'reclaim.slew_limits' must be [low, high] with low < high, got {list(r.slew_limits)}")
    if not 0 < r.cap_angle < 90:
        raise SceneError(f"{p}: 'reclaim.cap_angle' must lie in (0, 90) deg, got {r.cap_angle}")
    stops = {k: v for k, v in dataclasses.asdict(r.stop).items() if v is not None}
    if len(stops) != 1:
        raise SceneError(f"{p}: [reclaim.stop] needs exactly one of 'benches', 'tonnes' or 'time', got "
                         f"{', '.join(stops) or 'none'}")
    ((key, value),) = stops.items()
    if not value > 0:
        raise SceneError(f"{p}: 'reclaim.stop.{key}' must be > 0, got {value}")
    control = r.rate_control
    try:
        rate_control_class(control.type)
    except SceneError as exc:
        raise SceneError(f"{p}: {exc}") from None
    if not control.gain >= 0:
        raise SceneError(f"{p}: 'reclaim.rate_control.gain' must be >= 0, got {control.gain}")
    for key in ("integral_time", "filter_time", "calibration_time"):
        if not getattr(control, key) > 0:
            raise SceneError(f"{p}: 'reclaim.rate_control.{key}' must be > 0, got {getattr(control, key)}")
    low, high = control.trim_limits
    if not 0 < low <= 1 <= high:
        raise SceneError(f"{p}: 'reclaim.rate_control.trim_limits' must hold 0 < low <= 1 <= high, "
                         f"got {list(control.trim_limits)}")
    if control.type in ("wheel_power", "power_and_scale") and scene.digging is None:
        raise SceneError(f"{p}: 'reclaim.rate_control.type' \"{control.type}\" needs [digging]: "
                         "without a digging load the wheel's power does not follow the rate")
    if control.cutting_energy is not None and not control.cutting_energy > 0:
        raise SceneError(f"{p}: 'reclaim.rate_control.cutting_energy' must be > 0 J/m^3, got {control.cutting_energy}")


def _check_sensing(scene: Scene) -> None:
    """[sensing] and [reclaim.survey] against each other; the machine's scanners are checked as a run starts."""
    p, sensing = scene.path, scene.sensing
    if sensing.scanners and scene.stockpile is None:
        raise SceneError(f"{p}: 'sensing.scanners' is true, but the scene has no [stockpile] to scan")
    if sensing.rate_signals == "measured" and scene.reclaim is None:
        raise SceneError(f"{p}: 'sensing.rate_signals' \"measured\" is what a [reclaim]'s rate loop reads from the "
                         "belt scale and the wheel motor, but the scene has no [reclaim] of a pile: nothing would read them")
    survey = scene.reclaim.survey if scene.reclaim is not None else None
    if sensing.pile_model == "scanned":
        if scene.reclaim is None:
            raise SceneError(f"{p}: 'sensing.pile_model' \"scanned\" is the pile a [reclaim] is planned on, "
                             "but the scene has no [reclaim]")
        if sensing.scanners is False:
            raise SceneError(f"{p}: 'sensing.pile_model' \"scanned\" needs the scanners, but 'sensing.scanners' "
                             "is false")
    if survey is not None and not survey.waypoints:
        raise SceneError(f"{p}: 'reclaim.survey.waypoints' needs at least one waypoint [travel m, slew deg, "
                         "luff deg]")


def _check_interlock(scene: Scene) -> None:
    p, lock = scene.path, scene.interlock
    if lock is None:
        return
    if scene.stockpile is None and scene.neighbour is None:
        raise SceneError(f"{p}: [interlock] keeps the machine clear of the pile and of a neighbour, but the scene "
                         "has neither [stockpile] nor [neighbour]")
    if not 0 < lock.stop < lock.slow < lock.warn:
        raise SceneError(f"{p}: [interlock] zones must hold 0 < 'stop' < 'slow' < 'warn' m, got stop {lock.stop}, "
                         f"slow {lock.slow}, warn {lock.warn}")
    for key in ("reaction", "deceleration", "encoder_tolerance", "encoder_window"):
        if not getattr(lock, key) > 0:
            raise SceneError(f"{p}: 'interlock.{key}' must be > 0, got {getattr(lock, key)}")
    if not lock.hysteresis >= 0:
        raise SceneError(f"{p}: 'interlock.hysteresis' must be >= 0 m, got {lock.hysteresis}")
    if not 0 < lock.slow_share < 1:
        raise SceneError(f"{p}: 'interlock.slow_share' must lie in (0, 1), got {lock.slow_share}")
    if lock.encoder_window < scene.simulation.control_period:
        raise SceneError(f"{p}: 'interlock.encoder_window' must span at least a control period "
                         f"({scene.simulation.control_period} s), got {lock.encoder_window} s")
    try:
        interlock_class(lock.type)
    except SceneError as exc:
        raise SceneError(f"{p}: {exc}") from None


def _check_neighbour(scene: Scene) -> None:
    """[neighbour]'s schedule and numbers; its file and envelope are checked as a run starts."""
    p, neighbour = scene.path, scene.neighbour
    if neighbour is None:
        return
    if not neighbour.schedule:
        raise SceneError(f"{p}: 'neighbour.schedule' needs at least one step {{ t = 0.0, q = [travel, slew, luff] }}")
    times = [step.t for step in neighbour.schedule]
    for i in range(1, len(times)):
        if not times[i] > times[i - 1]:
            raise SceneError(f"{p}: 'neighbour.schedule[{i}]' t = {times[i]:g} s must come after schedule[{i - 1}]'s "
                             f"{times[i - 1]:g} s")
    if times[0] < 0:
        raise SceneError(f"{p}: 'neighbour.schedule[0]' t must be >= 0 s, got {times[0]:g}")
    if not neighbour.bandwidth > 0:
        raise SceneError(f"{p}: 'neighbour.bandwidth' must be > 0 rad/s, got {neighbour.bandwidth}")
    if not neighbour.report_delay >= 0:
        raise SceneError(f"{p}: 'neighbour.report_delay' must be >= 0 s, got {neighbour.report_delay}")


def _check_stacking(scene: Scene) -> None:
    """The rules of [stacking] that need no machine; the planner checks its reach."""
    p, s = scene.path, scene.stacking
    if scene.stockpile is not None or scene.digging is not None:
        raise SceneError(f"{p}: [stacking] builds its own pile on the bare yard: it takes no [stockpile] or [digging]")
    for key in ("rate", "tonnes", "bulk_density", "drop", "acceleration", "grid_spacing", "deposit_period",
                "row_spacing"):
        if not getattr(s, key) > 0:
            raise SceneError(f"{p}: 'stacking.{key}' must be > 0, got {getattr(s, key)}")
    if not 0 < s.angle_of_repose < 90:
        raise SceneError(f"{p}: 'stacking.angle_of_repose' must lie in (0, 90) deg, got {s.angle_of_repose}")
    if not s.layers >= 1:
        raise SceneError(f"{p}: 'stacking.layers' must be >= 1, got {s.layers}")
    if not s.max_layers >= 2:
        raise SceneError(f"{p}: 'stacking.max_layers' must be >= 2, got {s.max_layers}")
    if not abs(s.axis_x[1] - s.axis_x[0]) >= 4 * s.grid_spacing:
        raise SceneError(f"{p}: 'stacking.axis_x' must span at least 4 grid cells "
                         f"({4 * s.grid_spacing:g} m), got {list(s.axis_x)}")
    ratio = s.deposit_period / scene.simulation.control_period
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise SceneError(f"{p}: 'stacking.deposit_period' ({s.deposit_period} s) must be a whole multiple of "
                         f"'simulation.control_period' ({scene.simulation.control_period} s)")
    g = s.grade
    if (g.mean is None) == (g.file is None):
        raise SceneError(f"{p}: [stacking.grade] needs either a 'mean' (with 'sd' and 'correlation_time') or a "
                         "recorded 'file', not both")
    if g.sd < 0 or g.correlation_time < 0:
        raise SceneError(f"{p}: 'stacking.grade.sd' and 'correlation_time' must be >= 0, got {g.sd} and "
                         f"{g.correlation_time}")
    if g.file is not None and not g.file.is_file():
        raise SceneError(f"{p}: 'stacking.grade.file' names a file that does not exist: {g.file}")
    if g.band is not None and not g.band[0] < g.band[1]:
        raise SceneError(f"{p}: 'stacking.grade.band' must be [low, high] with low < high, got {list(g.band)}")


def _check_stockpile(scene: Scene) -> None:
    p, pile, digging = scene.path, scene.stockpile, scene.digging
    if digging is not None:
        if pile is None:
            raise SceneError(f"{p}: [digging] needs a [stockpile] to dig")
        for key in ("cutting_energy", "idle_power", "lateral_ratio"):
            if getattr(digging, key) < 0:
                raise SceneError(f"{p}: 'digging.{key}' must be >= 0, got {getattr(digging, key)}")
    if pile is None:
        return
    for key in ("bulk_density", "grid_spacing", "base_depth"):
        if not getattr(pile, key) > 0:
            raise SceneError(f"{p}: 'stockpile.{key}' must be > 0, got {getattr(pile, key)}")
    if not all(0 <= c <= 1 for c in pile.colour):
        raise SceneError(f"{p}: 'stockpile.colour' (rgba) must lie in [0, 1], got {list(pile.colour)}")
    if pile.angle_of_repose is not None and not 0 < pile.angle_of_repose < 90:
        raise SceneError(f"{p}: 'stockpile.angle_of_repose' must lie in (0, 90) deg, got {pile.angle_of_repose}")
    if (pile.windrow is None) == (pile.surface_file is None):
        raise SceneError(f"{p}: [stockpile] needs either a [stockpile.windrow] or a 'stockpile.surface_file', not both")
    if pile.surface_file is not None and not pile.surface_file.is_file():
        made_by_a_run = " (a run directory's pile: run the scene that stacks it first, or name its pile.npz with --pile)" \
            if pile.surface_file.name == "pile.npz" else ""
        raise SceneError(f"{p}: 'stockpile.surface_file' names a file that does not exist: "
                         f"{pile.surface_file}{made_by_a_run}")
    if pile.windrow is not None:
        w = pile.windrow
        for key in ("length", "height"):
            if not getattr(w, key) > 0:
                raise SceneError(f"{p}: 'stockpile.windrow.{key}' must be > 0, got {getattr(w, key)}")
        if w.crest_width < 0:
            raise SceneError(f"{p}: 'stockpile.windrow.crest_width' must be >= 0, got {w.crest_width}")
        if not 0 < w.angle_of_repose < 90:
            raise SceneError(f"{p}: 'stockpile.windrow.angle_of_repose' must lie in (0, 90) deg, got {w.angle_of_repose}")


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return _plain(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value

