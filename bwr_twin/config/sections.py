"""A scene's tables, typed: one frozen dataclass per TOML table, and the Scene they make.

Each field's type is the rule the builder (bwr_twin.config.builder) checks a file's value against;
its comment gives the unit and meaning. A number a scene may leave out takes its value from
scenes/defaults/scene_defaults.toml, where each has its source; a default here is a choice or "none".
Rules across fields live in bwr_twin.config.rules, physical ranges in bwr_twin.config.bounds.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from bwr_twin.config.faults import FaultSection
from bwr_twin.config.plugins import INTERLOCKS, RATE_CONTROLS, controller_class
from bwr_twin.values import is_number

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


@dataclass(frozen=True, kw_only=True)
class EncoderSection:
    resolution: Vec3  # m, rad, rad
    velocity_source: Literal["true", "encoder"] = "true"  # the plant's joint velocity, or estimated
    velocity_filter: float  # s, time constant of the encoder velocity estimate


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


@dataclass(frozen=True, kw_only=True)
class PlantSection:
    """Unmodelled effects: they act on the plant only, never on the controller's belief."""

    frictionloss: Vec3 | None = None  # Coulomb friction, N and N m; None keeps the MJCF's
    wind_speed: float = 0.0  # m/s, mean, blowing towards wind_direction
    wind_direction: float  # deg from world +X towards +Y
    gust_amplitude: float = 0.0  # m/s, uniform in [-a, a] around the mean
    gust_hold_time: float  # s, how long one gust lasts
    air_density: float  # kg/m^3, dry air at 20 degC
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


@dataclass(frozen=True, kw_only=True)
class StockpileSection:
    """The pile the wheel digs: a windrow, or a surveyed surface read from a file."""

    bulk_density: float  # kg/m^3, of the stockpiled (loose) material
    grid_spacing: float  # m between height samples
    windrow: WindrowSection | None = None
    surface_file: Path | None = None  # .npz with x, y (grid lines, m) and z (heights, m), or .csv x,y,z points
    # deg: the faces the wheel cuts slump to it, volume kept (bwr_twin.pile.cutting); None: they stand
    angle_of_repose: float | None = None
    # How the pile's hfield is drawn in the MuJoCo world (bwr_twin.model.spec), nothing else:
    colour: tuple[float, float, float, float] = (0.55, 0.27, 0.15, 1.0)  # rgba: iron ore's red-brown
    base_depth: float = 1.0  # m of the hfield's base box below the yard floor, as MuJoCo draws it


@dataclass(frozen=True, kw_only=True)
class DiggingSection:
    """The digging load: the wheel's cutting power P = cutting_energy x Q + idle_power, Q the
    volume it digs a second; the cutting force at the rim is that power over the rim speed."""

    cutting_energy: float  # J/m^3 of material dug
    idle_power: float = 0.0  # W, the wheel drive turning empty
    lateral_ratio: float  # force against the slewing, as a share of the tangential force


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


@dataclass(frozen=True, kw_only=True)
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
    gain: float  # trim per unit of relative rate error
    integral_time: float  # s
    filter_time: float  # s, first-order low-pass on the measured rate
    trim_limits: tuple[float, float]  # the slew speed within these multiples of the law's
    # "power_and_scale": the memory of the belt scale's correction to the power's calibration
    calibration_time: float  # s
    # J/m^3 the automation assumes to turn the wheel's power into a rate; None: [digging]'s own
    cutting_energy: float | None = None


@dataclass(frozen=True, kw_only=True)
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
    reaction: float  # s from a decision to the drives acting on it
    deceleration: float  # m/s^2 the drives brake the shapes at
    slow_share: float  # of the path's speed, in the slow zone
    hysteresis: float  # m beyond a zone's edge the predicted clearance must reach to leave it
    encoder_check: bool = True  # check the encoders against the drives' speed feedback
    encoder_tolerance: float  # m at the shapes the two may part by
    encoder_window: float  # s over which their motions are compared
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


@dataclass(frozen=True, kw_only=True)
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
    cap_angle: float  # deg: beyond it the cosine law holds its speed
    rate_control: RateControlSection
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


@dataclass(frozen=True, kw_only=True)
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
    row_spacing: float  # m between the rows of a stratum ("strata" only)
    drop: float  # m from the discharge point down to the crest
    acceleration: float  # m/s^2 of the travel as a pass starts and ends
    grid_spacing: float  # m between the pile's height samples
    deposit_period: float  # s between deposits: laid and slumped this often
    max_layers: int  # a column's layers (bwr_twin.stockpile.layers)


@dataclass(frozen=True)
class ScheduleStep:
    t: float  # s
    q: Vec3  # travel m, slew deg, luff deg


@dataclass(frozen=True, kw_only=True)
class NeighbourSection:
    """`[neighbour]`: a second machine on the same rail, from its own MJCF, simulated in the same
    world (docs/anticollision.md). It follows its `schedule`: where it stands at each time, at
    rest there, one cubic between (the path's law); before the first time and after the last it
    stands still. Its drives hold the schedule with a PD on its own inertia at its start,
    critically damped at `bandwidth`, gravity and bias compensated, within their force limits."""

    mjcf: Path
    schedule: tuple[ScheduleStep, ...]
    bandwidth: float  # rad/s of the drives' hold on the schedule
    report_delay: float  # s: the automation hears its position this late (its radio link)


@dataclass(frozen=True, kw_only=True)
class Scene:
    path: Path  # the scene file, for messages
    machine: MachineSection
    simulation: SimulationSection
    encoders: EncoderSection
    disturbance: DisturbanceSection
    controller: ControllerSection
    trajectory: PathSection | None = None  # via points, or
    reclaim: ReclaimSection | None = None  # a bench reclaim planned from the stockpile, or [stacking]
    plant: PlantSection
    stockpile: StockpileSection | None = None
    digging: DiggingSection | None = None
    sensing: SensingSection
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
TABLE_NAMES = {"trajectory": "path"}


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


