"""The rules of a scene that types alone do not express: a field against another, a table against
the tables it needs. Physical ranges are bwr_twin.config.bounds's; rules that need the machine are
checked as a run starts.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from bwr_twin.config.bounds import check_bounds
from bwr_twin.config.faults import check_faults
from bwr_twin.config.plugins import interlock_class, rate_control_class
from bwr_twin.config.sections import Scene
from bwr_twin.errors import SceneError


def check_rules(scene: Scene) -> None:
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

