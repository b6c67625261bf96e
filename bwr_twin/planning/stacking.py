"""A stacking pattern's path, planned once from the pile's target shape and the machine's reach,
as the bench planner plans a reclaim (docs/blending.md); bwr_twin.planning.patterns says which
passes each pattern lays, this module when and how fast.

The target is the ridge of the scene's tonnes: along the axis, standing at the angle of repose,
its section H^2 / tan(phi), so H = sqrt(V tan(phi) / L) for a volume V (the end cones left out).
Each pass holds the discharge point `drop` above the crest the target has reached once its layer
is laid (real stackers luff to hold their drop height, against dust and segregation), or as low
as the boom luffs where that is higher (the first layers of a low pile). The stream never stops:
the tonnes take tonnes / rate; between passes the machine turns, each joint a rest-to-rest cubic
at most at its rated speed and the discharge point at most at the travel's `acceleration` (no
turn where a pass starts where the last ended); the rest of the time is the passes', shared in
proportion to their weights. A moving pass runs a trapezoid in travel: `acceleration` up to the
cruise speed that takes exactly its time, the speed, then down, its slew and luff held, the axis
lying along the rail; a dwell stands still. What falls while the machine turns builds the end
cones of a real pile.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import EnvelopeError, SceneError, UnreachableError
from bwr_twin.model.machine import Machine, describe
from bwr_twin.planning.follower import Stage
from bwr_twin.planning.patterns import Pass, extent, lay, target_ridge
from bwr_twin.planning.trajectory import Trajectory, rest_to_rest
from bwr_twin.units import SECONDS_PER_HOUR

__all__ = ["StackingPlan", "pile_grid", "plan_stacking", "target_ridge"]

GRID_MARGIN = 2.0  # m of bare yard around the pile's foot: the relaxation's border is closed
LOWEST_MARGIN = 0.5  # m above the lowest the boom's head can luff to: room for the tracking error inside the envelope


@dataclass(frozen=True)
class StackingPlan:
    """The pattern's joint reference at every control period, the same for every run.

    Attributes:
        time: (samples,) s; rows: its (samples, 3) positions, velocities and accelerations.
        waypoints: the passes' ends as a via-point trajectory (for drawing; the rows are the path),
            `stages` what each is: "pass k" where pass k starts, "end" after the last.
        layout: the pattern's passes (bwr_twin.planning.patterns.Pass), in order.
        passes: (passes, 2) s each pass starts and ends (its cruise and both ramps, or its dwell).
        speeds: (passes,) m/s each pass cruises at, 0 for a dwell; `speed` the fastest.
        crests: (layers,) m the target's crest after each layer, cone or stratum
            (bwr_twin.planning.patterns.Layout); `height` the last.
        x, y: the pile's grid lines (m), wide enough for its foot and the end cones.
    """

    time: np.ndarray
    rows: tuple[np.ndarray, np.ndarray, np.ndarray]
    waypoints: Trajectory
    stages: tuple[Stage, ...]
    layout: tuple[Pass, ...]
    passes: np.ndarray
    speeds: np.ndarray
    crests: np.ndarray
    height: float
    speed: float
    x: np.ndarray
    y: np.ndarray


def plan_stacking(scene: Scene, machine: Machine, period: float) -> StackingPlan:
    """The scene's [stacking] pattern on `machine` at the control `period`. Raises SceneError,
    UnreachableError or EnvelopeError naming the scene and what does not fit."""
    s, p = scene.stacking, scene.path
    length = abs(s.axis_x[1] - s.axis_x[0])
    height, _ = target_ridge(s)
    _, foot = extent(s)
    if s.axis_y - foot < machine.rail_clearance:
        raise SceneError(f"{p}: the pile's foot would reach y = {s.axis_y - foot:.2f} m ({s.tonnes:g} t on a "
                         f"{length:g} m axis stand {height:.2f} m high, {foot:.2f} m to each side), inside the "
                         f"{machine.rail_clearance:g} m the rail keeps clear ('rail_clearance' of {machine.path.name}): "
                         "move 'stacking.axis_y' out or lengthen the axis")
    g = machine.geometry  # the head no lower than the boom luffs: the first layers fall farther
    lowest = g.pivot_height + g.boom_length * math.sin(g.boom_angle0 + machine.envelope[2, 0]) + LOWEST_MARGIN
    layout = lay(s, lowest, p)
    knots = []  # each pass's start and end
    for k, lane in enumerate(layout.passes):
        if lane.dwell:
            q = _ik(machine, p, (lane.start, lane.y, lane.head), f"pass {k + 1}")
            knots.append([q, q])
            continue
        knots.append([_ik(machine, p, (x, lane.y, lane.head), f"pass {k + 1}'s {which}")
                      for x, which in ((lane.start, "start"), (lane.end, "end"))])
    count = len(knots)
    turns = [_turn_time(machine, knots[i][1], knots[i + 1][0], s.acceleration) for i in range(count - 1)]
    total = s.tonnes / s.rate * SECONDS_PER_HOUR
    left = total - sum(turns)  # s the passes share
    if not left > 0:
        raise SceneError(f"{p}: [stacking]'s turns between its {count} passes take {sum(turns):.1f} s, all the "
                         f"{total:.1f} s the stream takes ({s.tonnes:g} t at {s.rate:g} t/h): {layout.fewer}, "
                         "more tonnes or a lower rate")
    weight = sum(lane.weight for lane in layout.passes)
    durations = [left * lane.weight / weight for lane in layout.passes]  # s of each pass
    cruises = _cruises(p, layout, durations, machine, s)
    segments, passes, t = [], [], 0.0  # (start s, end s, kind, from, to, cruise m/s, ramp s)
    for k, (lane, duration, (speed, ramp)) in enumerate(zip(layout.passes, durations, cruises)):
        a, b = knots[k]
        segments.append((t, t + duration, "dwell" if lane.dwell else "pass", a, b, speed, ramp))
        passes.append((t, t + duration))
        t += duration
        if k < count - 1 and turns[k] > 0:  # none where the next pass starts where this one ends
            segments.append((t, t + turns[k], "turn", b, knots[k + 1][0], 0.0, 0.0))
            t += turns[k]
    samples = round(total / period) + 1
    time = np.arange(samples) * period
    rows = _sample(segments, time, s.acceleration)
    stops, ends_of = np.array([edge for segment in passes for edge in segment]), [q for pair in knots for q in pair]
    kinds = [stage for k in range(count) for stage in (Stage("pass", k + 1), Stage("move"))]
    kinds[-1] = Stage("end")
    kept = np.concatenate([[True], np.diff(stops) > 0])  # a pass that starts where the last ended, once
    stages = _kept_stages(kinds, kept)
    joints = np.array(ends_of)[kept]
    waypoints = Trajectory(times=stops[kept], knots=joints, points=np.array([machine.fk(q) for q in joints]))
    x, y = pile_grid(s)
    speeds = np.array([speed for speed, _ in cruises])
    return StackingPlan(time, rows, waypoints, stages, layout.passes, np.array(passes), speeds, layout.crests,
                        float(layout.crests[-1]), float(speeds.max()), x, y)


def _kept_stages(stages: list[Stage], kept: np.ndarray) -> tuple[Stage, ...]:
    """The stages of the waypoints kept: where a pass starts as the last one ends, it names the point."""
    out: list[Stage] = []
    for stage, keep in zip(stages, kept):
        if keep:
            out.append(stage)
        else:
            out[-1] = stage
    return tuple(out)


def pile_grid(section) -> tuple[np.ndarray, np.ndarray]:
    """The grid lines (m) of a [stacking]'s pile: its extent (bwr_twin.planning.patterns) and
    GRID_MARGIN around it."""
    along, across = extent(section)
    reach = along + GRID_MARGIN
    x = _lines(min(section.axis_x) - reach, max(section.axis_x) + reach, section.grid_spacing)
    y = _lines(section.axis_y - across - GRID_MARGIN, section.axis_y + across + GRID_MARGIN, section.grid_spacing)
    return x, y


def _ik(machine: Machine, scene_path, point: tuple[float, float, float], label: str) -> np.ndarray:
    try:
        return machine.ik(np.array(point), label=f"[stacking] {label}")
    except (UnreachableError, EnvelopeError) as exc:
        raise type(exc)(f"{scene_path}: {exc}") from None


def _turn_time(machine: Machine, start: np.ndarray, end: np.ndarray, acceleration: float) -> float:
    """s of a rest-to-rest cubic from `start` to `end` whose top speed (1.5 x delta / span) is
    each joint's rated speed at most, and whose top acceleration (6 x delta / span^2) moves the
    discharge point at `acceleration` (m/s^2) at most: a rotation's over the boom's length."""
    levers = np.array([1.0, machine.geometry.boom_length, machine.geometry.boom_length])  # m a unit of each moves the CP
    delta = np.abs(end - start)
    return float(max(np.max(1.5 * delta / machine.rated_speed), np.max(np.sqrt(6.0 * delta * levers / acceleration))))


def _cruises(scene_path, layout, durations: list[float], machine: Machine, section) -> list[tuple[float, float]]:
    """Each pass's cruise speed (m/s) and ramps' time (s), (0, 0) for a dwell. SceneError, naming
    the pass and what to change, for the first that cannot take its time or cruises faster than
    the travel's rated speed."""
    moving = [d for lane, d in zip(layout.passes, durations) if not lane.dwell]
    uniform = len(set(moving)) <= 1
    count = len(layout.passes)
    out = []
    for k, (lane, duration) in enumerate(zip(layout.passes, durations)):
        if lane.dwell:
            out.append((0.0, 0.0))
            continue
        names = ((f"each of its {count} passes", "passes") if uniform
                 else (f"pass {k + 1} of its {count} passes", f"pass {k + 1}"))
        out.append(_cruise(scene_path, abs(lane.end - lane.start), section.acceleration, duration, machine,
                           section, names, layout.fewer))
    return out


def _cruise(scene_path, length: float, acceleration: float, duration: float, machine: Machine, section,
            names: tuple[str, str], fewer: str) -> tuple[float, float]:
    """The cruise speed (m/s) of a trapezoid over `length` m at `acceleration` that takes
    `duration` s, and its ramps' time (s). SceneError if no such trapezoid exists, or if it
    cruises faster than the travel's rated speed, naming the pass (`names`: as the time's owner
    and as the subject) and `fewer`, what lengthens it."""
    which, who = names
    need = 2.0 * math.sqrt(length / acceleration)  # the fastest: up and straight down again
    if not duration >= need:
        raise SceneError(f"{scene_path}: [stacking] leaves {which} {duration:.1f} s "
                         f"({section.tonnes:g} t at {section.rate:g} t/h), less than the {need:.1f} s a "
                         f"{length:g} m pass takes at {acceleration:g} m/s^2: {fewer}, or a shorter axis")
    # duration = length / v + v / a: the smaller root, the one that cruises
    speed = 0.5 * acceleration * (duration - math.sqrt(duration**2 - 4.0 * length / acceleration))
    rated = machine.rated_speed[0]
    if speed > rated:
        raise SceneError(f"{scene_path}: [stacking]'s {who} would cruise at {speed:.3f} m/s, above the travel's rated "
                         f"{describe(0, rated)}/s ({machine.path.name}): {fewer}, a shorter axis or a lower rate")
    return speed, speed / acceleration


def _sample(segments, time: np.ndarray, acceleration: float):
    """(samples, 3) positions, velocities and accelerations of the segments at `time`."""
    q, qd, qdd = (np.zeros((len(time), 3)) for _ in range(3))
    starts = np.array([segment[0] for segment in segments])
    which = np.clip(np.searchsorted(starts, time, side="right") - 1, 0, len(segments) - 1)
    for i, (t0, t1, kind, a, b, speed, ramp) in enumerate(segments):
        rows = which == i
        t = np.clip(time[rows] - t0, 0.0, t1 - t0)
        if kind == "turn":
            span = t1 - t0
            q[rows], qd[rows], qdd[rows] = rest_to_rest(a, b, span, (t / span)[:, None])
            continue
        q[rows] = a
        if kind == "dwell":  # standing still, discharging: at rest
            continue
        direction = math.copysign(1.0, b[0] - a[0])
        distance, velocity, accel = _trapezoid(t, t1 - t0, abs(b[0] - a[0]), speed, acceleration, ramp)
        q[rows, 0] = a[0] + direction * distance
        qd[rows, 0], qdd[rows, 0] = direction * velocity, direction * accel
    return q, qd, qdd


def _trapezoid(t: np.ndarray, duration: float, length: float, speed: float, acceleration: float, ramp: float):
    """Distance, speed and acceleration at t s of a pass over `length` m: up at `acceleration`
    for `ramp` s, `speed`, then down, ending at rest at `duration` s."""
    left = duration - t
    up, down = t < ramp, left < ramp
    distance = np.where(up, 0.5 * acceleration * t**2,
                        np.where(down, length - 0.5 * acceleration * left**2, 0.5 * speed * ramp + speed * (t - ramp)))
    velocity = np.where(up, acceleration * t, np.where(down, acceleration * left, speed))
    accel = np.where(up, acceleration, np.where(down, -acceleration, 0.0))
    return distance, velocity, accel


def _lines(low: float, high: float, spacing: float) -> np.ndarray:
    """Grid lines every `spacing` m from a multiple of it at or below `low` to one at or above `high`."""
    first, last = math.floor(low / spacing), math.ceil(high / spacing)
    return np.arange(first, last + 1) * spacing
