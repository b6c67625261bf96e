"""Bench reclaiming planned from the pile: where the wheel lands, how far each slew pass goes,
when the boom steps down (docs/reclaiming.md).

The reclaimer works the pile's face in benches, from the top. At a bench's luff the wheel's
lowest point is the bench's floor; the travel lands the wheel on the face, then each slew pass
cuts a crescent across the face between the pile's edges, the travel advances one cut depth at
the end of the pass, and the next pass slews back. After `bench_length` of travel the boom
slews clear, the travel backs off and the boom steps down to the next bench.

Nothing is assumed of the pile's shape: the planner digs a copy of it with the twin's own cut
(bwr_twin.pile.cutting) as it plans, so it finds the face and the edges of every pass on the
pile as the passes before it leave it, and predicts what each pass reclaims.

The plan (bwr_twin.planning.plan) is a list of segments: `Move`s (smooth joint-space cubics, at
rest at both ends, within the rated speeds and the scene's accelerations) and `Pass`es (a slew
at the bench's travel and luff whose speed is decided while the run goes: the speed law, trimmed
by the rate control; bwr_twin.planning.follower). A plan that cannot be carried out is refused
with a SceneError before anything is simulated.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bwr_twin.config.sections import ReclaimSection, Scene, StockpileSection
from bwr_twin.errors import EnvelopeError, SceneError
from bwr_twin.model.machine import AXES, Machine, describe
from bwr_twin.pile.cutting import Cutter
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.surface import Surface, build_surface
from bwr_twin.planning.plan import BenchPlan, Move, Pass, SpeedLaw, end_of
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR

PROBE_STEP = 0.25  # m the wheel moves between cuts when the planner looks for the pile: one grid cell
DIG_STEP = 0.05  # m the wheel moves between cuts when the planner digs its copy of the pile
LANDING_TOLERANCE = 0.01  # m of travel to which the landing is found
SEARCH_STEP = 2.0  # m of travel between looks for the face
FULL_FACE = 0.9  # a pass cuts steadily where its face's section is at least this share of the full one
SMOOTHING = 1.0  # m of the wheel's travel over which the predicted section is averaged
MIN_MOVE = 1.0  # s: the shortest move


def plan_scene(scene: Scene) -> BenchPlan:
    """The bench plan of a scene with [reclaim], on its pile and machine (with its payloads);
    SceneError naming the key and the limit if it cannot be done. Planned once per scene.

    With a [reclaim.survey], the survey's moves come first and the benches are planned from where
    they leave the machine, here on the true pile: what a run on its scanned pile expects (it plans
    its own benches at the survey's end, `plan_after_survey`)."""
    survey = survey_plan(scene)
    if survey is None:
        return _plan(scene.reclaim, scene.stockpile, scene.machine.mjcf, scene.plant.payload,
                     scene.simulation.control_period, scene.path)
    benches = _plan(scene.reclaim, scene.stockpile, scene.machine.mjcf, scene.plant.payload,
                    scene.simulation.control_period, scene.path, tuple(survey.segments[-1].end.tolist()),
                    survey.nominal_duration)
    return after_survey(survey, benches)


@functools.lru_cache(maxsize=8)
def survey_plan(scene: Scene) -> BenchPlan | None:
    """The [reclaim.survey]'s moves through its waypoints from 'start', as a plan of moves alone;
    None without a survey. SceneError naming the waypoint if one is outside the envelope."""
    reclaim = scene.reclaim
    if reclaim.survey is None:
        return None
    machine = Machine.shared(scene.machine.mjcf, scene.plant.payload)
    where = f"{scene.path}: [reclaim]"
    planner = _Planner(reclaim, machine, None, scene.stockpile.bulk_density, scene.simulation.control_period, where)
    moves, q = [], planner.start.q
    for i, (travel, slew, luff) in enumerate(reclaim.survey.waypoints):
        waypoint = np.array([travel, np.radians(slew), np.radians(luff)])
        try:
            machine.check_envelope(waypoint, label=f"'survey.waypoints[{i + 1}]'")
        except EnvelopeError as exc:
            raise SceneError(f"{where}: {exc}") from None
        moves.append(planner.quickest_move(q, waypoint, 0, "survey"))
        q = waypoint
    duration = sum(m.duration for m in moves)
    if reclaim.stop.time is not None and reclaim.stop.time <= duration:
        # The benches are planned for the time left after the survey: none would be left.
        raise SceneError(f"{where}: 'stop.time' = {reclaim.stop.time:g} s ends within the survey, which takes "
                         f"{duration:.1f} s through its {len(moves)} waypoints ([reclaim.survey]); a stop "
                         "time counts from the run's start and must come after the survey's end")
    limits = planner.limits
    return BenchPlan(tuple(moves), planner.start.q, planner.law, limits.acceleration, limits.rated, None, (),
                     scene.stockpile.bulk_density, duration, duration + planner.period)


def plan_after_survey(scene: Scene, machine: Machine, heights: np.ndarray) -> BenchPlan:
    """The survey's moves, then the benches planned from where they leave the machine on the pile
    of `heights` (ny, nx) m on the scene's grid: the pile a run knows from its scans, where a
    cell no scan has reached (NaN) counts as the yard floor. SceneError if no bench can be planned."""
    survey = survey_plan(scene)
    surface = build_surface(scene.stockpile, scene.path)
    known = Surface(surface.x, surface.y, np.where(np.isnan(heights), YARD_FLOOR, heights))
    where = f"{scene.path}: [reclaim] on the pile scanned by the survey"
    planner = _Planner(scene.reclaim, machine, known, scene.stockpile.bulk_density,
                       scene.simulation.control_period, where, survey.segments[-1].end, survey.nominal_duration,
                       scene.stockpile.angle_of_repose)
    return after_survey(survey, planner.plan())


def after_survey(survey: BenchPlan, benches: BenchPlan) -> BenchPlan:
    """One plan: the survey's moves, then the benches planned from where they end."""
    return replace(benches, segments=survey.segments + benches.segments, start=survey.start,
                   nominal_duration=survey.nominal_duration + benches.nominal_duration,
                   longest_duration=survey.nominal_duration + benches.longest_duration)


@functools.lru_cache(maxsize=8)
def _plan(reclaim: ReclaimSection, stockpile: StockpileSection, mjcf: Path, payload: tuple, period: float,
          scene_path: Path, start: tuple | None = None, elapsed: float = 0.0) -> BenchPlan:
    machine = Machine.shared(mjcf, payload)
    surface = build_surface(stockpile, scene_path)
    where = f"{scene_path}: [reclaim]"
    return _Planner(reclaim, machine, surface, stockpile.bulk_density, period, where,
                    None if start is None else np.array(start), elapsed, stockpile.angle_of_repose).plan()


@dataclass(frozen=True)
class MoveLimits:
    """How the machine may move while it reclaims: (3,) accelerations (m/s^2, rad/s^2) and rated
    speeds (m/s, rad/s) of travel, slew and luff, and the slew's (low, high) limits (rad)."""

    acceleration: np.ndarray
    rated: np.ndarray
    slew_limits: tuple[float, float]


@dataclass(frozen=True)
class _Start:
    """Where a plan starts (3,) and how a refusal names it: 'start' or a survey's last waypoint."""

    q: np.ndarray
    name: str


class _Planner:
    def __init__(self, settings: ReclaimSection, machine: Machine, surface: Surface | None, density: float,
                 period: float, where: str, start: np.ndarray | None = None, elapsed: float = 0.0,
                 angle_of_repose: float | None = None):
        """`start` (3,): where the plan starts, if not at 'start' (a survey's end), `elapsed` s
        after the run's start (a stop after a time counts from the run's start). Without a
        `surface` it plans moves alone. `angle_of_repose` (deg): the faces its pile's cuts leave
        slump to it, as the run's will (None: they stand)."""
        if elapsed and settings.stop.time is not None:
            settings = replace(settings, stop=replace(settings.stop, time=settings.stop.time - elapsed))
        self.s, self.machine, self.surface, self.density, self.period = settings, machine, surface, density, period
        self.where = where
        wheel = machine.wheel
        if wheel is None:
            raise SceneError(f"{where}: {machine.path.name} describes no bucket wheel: it cannot reclaim")
        self.wheel = wheel
        self.limits = MoveLimits(np.array([settings.acceleration[0], *np.radians(settings.acceleration[1:])]),
                                 machine.rated_speed, tuple(np.radians(settings.slew_limits)))
        self.start = (_Start(np.array([settings.start[0], *np.radians(settings.start[1:])]), "'start'")
                      if start is None else _Start(start, "the survey's last waypoint"))
        self._check_settings()
        self.law = SpeedLaw(settings.target_rate * KG_PER_T / SECONDS_PER_HOUR / density, settings.speed_law,
                            np.radians(settings.cap_angle), float(self.limits.rated[1]))
        if surface is None:
            return
        self.dig = Cutter(surface, wheel, 1, angle_of_repose)  # the planner's copy of the pile, dug as it plans
        self.top = float(surface.z.max())
        g = machine.geometry
        cp0 = machine.fk(self.start.q)
        centre = float(np.average(surface.x, weights=np.maximum(surface.z, 0).sum(axis=0) + 1e-12))
        self.ahead = 1.0 if centre >= cp0[0] else -1.0  # the travel's direction into the pile
        self.slew_axis = np.array(g.slew_axis_xy)
        self.first_contact: np.ndarray | None = None

    # -- refusals that need no pile -----------------------------------------------------------

    def _check_settings(self) -> None:
        s, wheel, where, machine = self.s, self.wheel, self.where, self.machine
        share = wheel.bench_share  # the MJCF's 'wheel_bench_share' (docs/reclaiming.md)
        if s.bench_height > share * wheel.diameter + 1e-9:
            raise SceneError(
                f"{where}: 'bench_height' {s.bench_height:g} m is more than {share:g} x the wheel's "
                f"{wheel.diameter:g} m diameter ({share * wheel.diameter:g} m): the buckets would not "
                "clear the face"
            )
        capacity = wheel.capacity * self.density * SECONDS_PER_HOUR / KG_PER_T
        if s.target_rate > capacity:
            raise SceneError(
                f"{where}: 'target_rate' {s.target_rate:,.0f} t/h is beyond the wheel's capacity of {capacity:,.0f} "
                f"t/h ({wheel.discharges_per_minute:g} discharges a minute of {wheel.bucket_volume:g} m3 buckets, "
                f"at {self.density:g} kg/m3)"
            )
        if s.cut_depth > wheel.radius:
            raise SceneError(f"{where}: 'cut_depth' {s.cut_depth:g} m is more than the wheel's radius "
                             f"{wheel.radius:g} m")
        low, high = machine.envelope[1]
        for value, label in zip(self.limits.slew_limits, ("low", "high")):
            if not low - 1e-9 <= value <= high + 1e-9:
                raise SceneError(f"{where}: 'slew_limits' ({label}) {np.degrees(value):g} deg is outside the slew "
                                 f"envelope [{describe(1, low)}, {describe(1, high)}] of {machine.path.name}")
        try:
            machine.check_envelope(self.start.q, label="'start'")
        except EnvelopeError as exc:
            raise SceneError(f"{where}: {exc}") from None
        self._check_drives()

    def _check_drives(self) -> None:
        """The references' accelerations, held against gravity at the start, within each drive's rating."""
        machine, where = self.machine, self.where
        mass, biases = machine.dynamics.at(self.start.q, np.zeros(3))
        for j, axis in enumerate(AXES):
            need = mass[j, j] * self.limits.acceleration[j]
            low, high = machine.drive_limits[j]
            bias = biases[j]
            if bias + need > high or bias - need < low:
                unit, force = ("m/s2", "N") if j == 0 else ("deg/s2", "N m")
                shown = self.limits.acceleration[j] if j == 0 else np.degrees(self.limits.acceleration[j])
                held = f" on top of {abs(bias):.3g} {force} against gravity" if abs(bias) > 1e-6 * need else ""
                raise SceneError(
                    f"{where}: 'acceleration' ({axis}) {shown:g} {unit} needs {need:.3g} {force}{held} at 'start', "
                    f"beyond the {axis} drive's rating [{low:.3g}, {high:.3g}] {force}"
                )

    # -- the plan -----------------------------------------------------------------------------

    def plan(self) -> BenchPlan:
        s = self.s
        segments: list[Move | Pass] = []
        volumes: list[float] = []
        q = self.start.q
        nominal = 0.0
        stop = s.stop
        bench = 0
        while True:
            if stop.benches is not None and bench == stop.benches:
                break
            tonnes = sum(volumes) * self.density / KG_PER_T
            if stop.tonnes is not None and tonnes >= stop.tonnes:
                break
            if stop.time is not None and nominal >= stop.time:
                break
            planned = self._bench(bench, q, len([x for x in segments if isinstance(x, Pass)]))
            if planned is None:  # nothing left within reach
                if stop.benches is not None or bench == 0:
                    raise SceneError(self._nothing_left(bench))
                if stop.tonnes is not None:
                    raise SceneError(f"{self.where}: the pile within reach holds {tonnes:,.0f} t in {bench} "
                                     f"bench(es), less than 'stop.tonnes' {stop.tonnes:,.0f} t")
                break
            bench_segments, volume = planned
            segments += bench_segments
            volumes.append(volume)
            nominal += sum(self._nominal_time(x) for x in bench_segments)
            q = end_of(bench_segments[-1])
            bench += 1
        low_trim = s.rate_control.trim_limits[0]
        ramp = self._fastest(self.start.q[2]) / self.limits.acceleration[1]  # s to reach or leave the fastest slew
        longest = sum(x.duration if isinstance(x, Move) else self._nominal_time(x) / low_trim + 2 * ramp
                      for x in segments)
        if stop.time is not None:
            longest = min(longest, stop.time + ramp + self.period)
            nominal = min(nominal, stop.time)
        limits = self.limits
        return BenchPlan(tuple(segments), self.start.q, self.law, limits.acceleration, limits.rated, self.first_contact,
                         tuple(volumes), self.density, nominal, longest + self.period)

    def _nothing_left(self, bench: int) -> str:
        return (f"{self.where}: bench {bench + 1} (floor at {self._floor(bench):.2f} m) finds no pile within "
                f"'slew_limits' {list(self.s.slew_limits)} deg along the travel envelope from 'start'")

    def _floor(self, bench: int) -> float:
        return self.top - (bench + 1) * self.s.bench_height

    def _bench(self, bench: int, q: np.ndarray, passes_before: int) -> tuple[list[Move | Pass], float] | None:
        """The segments of one bench from q, and the volume they cut; None if the bench has no pile."""
        s, wheel = self.s, self.wheel
        floor = self._floor(bench)
        if floor < float(self.surface.z.min()) - 1e-9 and bench > 0:
            return None  # down to the ground
        luff = self._luff_for(floor + wheel.radius, bench)
        landing = self._landing(luff, bench)
        if landing is None:
            return None
        count = max(int(round(s.bench_length / s.cut_depth)), 1)
        travels = [landing + self.ahead * s.cut_depth * (i + 1) for i in range(count)]
        windows = []
        for travel in travels:
            self._check_travel(travel, bench)
            window = self._window(travel, luff)
            if window is None:
                break  # the pile ends along the rail
            windows.append(window)
        if not windows:
            return None
        travels = travels[: len(windows)]
        ascending = abs(q[1] - self.limits.slew_limits[0]) <= abs(q[1] - self.limits.slew_limits[1])
        # Each pass turns beyond the edges of both passes that meet there.
        margin = self._margin(luff)
        turns = []
        for i in range(len(windows) + 1):
            up = ascending if i % 2 == 0 else not ascending  # the direction of pass i (or the last one's end)
            near = [w for w in windows[max(i - 1, 0) : i + 1]]
            if up:
                turn = min(w[0] for w in near) - margin
            else:
                turn = max(w[1] for w in near) + margin
            turns.append(float(np.clip(turn, *self.limits.slew_limits)))
        segments: list[Move | Pass] = []
        volume = 0.0
        # Onto the bench: from the last bench, slew clear, then travel and luff together.
        target = np.array([travels[0], turns[0], luff])
        if bench == 0:
            segments.append(self.quickest_move(q, target, bench, "approach"))
        else:
            clear = np.array([q[0], turns[0], q[2]])
            segments.append(self.quickest_move(q, clear, bench, "slew clear"))
            segments.append(self.quickest_move(clear, target, bench, "step down"))
        for segment in segments:
            volume += self._dig_move(segment)
        for i, travel in enumerate(travels):
            start, end = turns[i], turns[i + 1]
            if i > 0:
                step = self.quickest_move(np.array([travels[i - 1], start, luff]), np.array([travel, start, luff]), bench,
                                  "travel step")
                segments.append(step)
                volume += self._dig_move(step)
            p = self._dig_pass(travel, luff, start, end, bench, passes_before + i + 1)
            self._check_speed(p)
            segments.append(p)
            volume += p.volume
        return segments, volume

    def _check_speed(self, p: Pass) -> None:
        """The speed law within the slew drive's rating wherever the pass cuts."""
        angles = np.linspace(*p.cut, 50)
        speeds = np.array([self.law.speed(p, a) for a in angles])
        worst = int(np.argmax(speeds))
        if speeds[worst] > self.law.rated * (1 + 1e-9):
            raise SceneError(
                f"{self.where}: 'target_rate' {self.s.target_rate:,.0f} t/h needs a slew speed of "
                f"{np.degrees(speeds[worst]):.3f} deg/s at slew {np.degrees(angles[worst]):.1f} deg (pass "
                f"{p.number}, bench {p.bench + 1}), beyond the slew drive's rated "
                f"{np.degrees(self.law.rated):.3f} deg/s: lower 'target_rate', or raise 'cut_depth' or "
                "'bench_height', or narrow 'slew_limits'"
            )

    def _luff_for(self, height: float, bench: int) -> float:
        """The luff that puts the wheel's centre at `height`; SceneError if the envelope has none."""
        g, machine = self.machine.geometry, self.machine
        ratio = (height - g.pivot_height) / g.boom_length
        low, high = machine.envelope[2]
        luff = float(np.arcsin(ratio)) - g.boom_angle0 if abs(ratio) <= 1 else np.inf * np.sign(ratio)
        if not low - 1e-9 <= luff <= high + 1e-9:
            reach = (g.pivot_height + g.boom_length * np.sin(g.boom_angle0 + np.array([low, high]))
                     - self.wheel.radius)
            raise SceneError(
                f"{self.where}: bench {bench + 1}'s floor at {height - self.wheel.radius:.2f} m (pile top "
                f"{self.top:.2f} m less {bench + 1} x 'bench_height' {self.s.bench_height:g} m) is out of the "
                f"wheel's reach: the luff envelope puts the wheel's lowest point between {reach[0]:.2f} and "
                f"{reach[1]:.2f} m"
            )
        return luff

    def _check_travel(self, travel: float, bench: int) -> None:
        low, high = self.machine.envelope[0]
        if not low - 1e-9 <= travel <= high + 1e-9:
            raise SceneError(f"{self.where}: bench {bench + 1} needs travel {travel:.2f} m, outside the travel "
                             f"envelope [{low:g}, {high:g}] m of {self.machine.path.name}")

    def _radius(self, luff: float) -> float:
        """m from the slew axis to the wheel's centre at `luff`."""
        return float(np.hypot(*(self.machine.fk(np.array([0.0, 0.0, luff]))[:2] - self.slew_axis)))

    def _fastest(self, luff: float) -> float:
        """rad/s: the fastest slew a trimmed speed law may ask at `luff` (the law at its cap)."""
        at_cap = self.law.volume_rate / (self.s.bench_height * self.s.cut_depth * np.cos(self.law.cap)
                                         * self._radius(luff))
        return min(self.law.rated, at_cap * self.s.rate_control.trim_limits[1])

    def _margin(self, luff: float) -> float:
        """rad beyond a pass's cut: room to reach the fastest speed, and the wheel's clearance
        (the MJCF's 'wheel_clearance')."""
        return self._fastest(luff) ** 2 / (2 * self.limits.acceleration[1]) + self.wheel.clearance / self._radius(luff)

    def _arc(self, travel: float, luff: float, start: float, end: float, step: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint values (n, 3) and CP (n, 3) along a slew from start to end, the wheel moving `step` m apart."""
        cp = self.machine.fk(np.array([travel, start, luff]))
        radius = float(np.hypot(*(cp[:2] - self.slew_axis - [travel, 0.0])))
        count = max(int(np.ceil(abs(end - start) * radius / step)), 1) + 1
        q = np.column_stack([np.full(count, travel), np.linspace(start, end, count), np.full(count, luff)])
        return q, self.machine.fk(q)

    def _probe(self, travel: float, luff: float) -> np.ndarray:
        """Slew angles across the slew limits at which the wheel would cut the planner's pile (not dug)."""
        q, cp = self._arc(travel, luff, *self.limits.slew_limits, PROBE_STEP)
        probe = Cutter(Surface(self.surface.x, self.surface.y, self.dig.heights[0]), self.wheel, 1)
        cutting = np.zeros(len(q), dtype=bool)
        for i in range(len(q)):
            cutting[i] = probe.cut(cp[i : i + 1], q[i : i + 1, 1]).volume[0] > 0
        return q[cutting, 1]

    def _window(self, travel: float, luff: float) -> tuple[float, float] | None:
        angles = self._probe(travel, luff)
        return (float(angles.min()), float(angles.max())) if angles.size else None

    def _landing(self, luff: float, bench: int) -> float | None:
        """The travel at which a slew across the limits first touches the pile: clear behind it,
        in the pile ahead of it; None if the wheel meets no pile along the envelope."""
        low, high = self.machine.envelope[0]
        clear = float(self.start.q[0])
        if self._window(clear, luff) is not None:
            raise SceneError(
                f"{self.where}: at {self.start.name} travel {clear:g} m the wheel would already cut the pile on bench "
                f"{bench + 1}: start farther from the pile"
            )
        deep = clear
        while True:
            deep += self.ahead * SEARCH_STEP
            if not low <= deep <= high:
                return None
            if self._window(deep, luff) is not None:
                break
            clear = deep
        while abs(deep - clear) > LANDING_TOLERANCE:
            middle = 0.5 * (clear + deep)
            if self._window(middle, luff) is None:
                clear = middle
            else:
                deep = middle
        return clear

    # -- digging the planner's pile -----------------------------------------------------------

    def _cut(self, q: np.ndarray, cp: np.ndarray) -> np.ndarray:
        """Dig the planner's pile along joint values q (n, 3); the volume each one cuts (n,)."""
        volumes = np.zeros(len(q))
        for i in range(len(q)):
            cut = self.dig.cut(cp[i : i + 1], q[i : i + 1, 1])
            self.dig.slump(cut)
            volumes[i] = cut.volume[0]
            if volumes[i] > 0 and self.first_contact is None:
                self.first_contact = cp[i].copy()
        return volumes

    def _dig_move(self, move: Move) -> float:
        path = np.abs(self.machine.fk(move.end) - self.machine.fk(move.start)).sum()
        count = max(int(np.ceil(path / DIG_STEP)), 1) + 1
        q = np.array([move.sample(t)[0] for t in np.linspace(0.0, move.duration, count)])
        return float(self._cut(q, self.machine.fk(q)).sum())

    def _dig_pass(self, travel: float, luff: float, start: float, end: float, bench: int, number: int) -> Pass:
        q, cp = self._arc(travel, luff, start, end, DIG_STEP)
        volumes = self._cut(q, cp)
        slew = q[:, 1]
        cutting = np.flatnonzero(volumes > 0)
        height = min(self.s.bench_height, self.top - self._floor(bench))
        radius = float(np.hypot(*(cp[0, :2] - self.slew_axis - [travel, 0.0]))) + self._face_offset(height)
        cut = (float(slew[cutting[0]]), float(slew[cutting[-1]])) if cutting.size else (start, start)
        p = Pass(travel=travel, luff=luff, start=start, end=end, bench=bench, number=number, cut=cut, steady=None,
                 face_height=height, cut_depth=self.s.cut_depth, radius=radius, volume=float(volumes.sum()))
        # Steady cutting: where the face's section (averaged over SMOOTHING of the wheel's motion)
        # is the full one, the bench's height x the cut across the face, cut_depth x |cos(slew)|.
        window = max(int(round(SMOOTHING / DIG_STEP)), 1)
        moved = abs(slew[1] - slew[0]) * radius if len(slew) > 1 else DIG_STEP
        section = np.convolve(volumes, np.ones(window) / window, mode="same") / moved
        steady = _longest_run(section >= FULL_FACE * height * self.s.cut_depth * np.abs(np.cos(slew)))
        if steady is None:
            return p
        return replace(p, steady=(float(slew[steady[0]]), float(slew[steady[1]])))

    def _face_offset(self, height: float) -> float:
        """How far beyond the wheel's centre, along the boom, the face's centre of area lies: the
        mean over the bench's height of the wheel circle's half chord."""
        r = self.wheel.radius
        y = np.linspace(0.0, height, 201)
        return float(np.mean(np.sqrt(np.maximum(r**2 - (r - y) ** 2, 0.0))))

    # -- timing -------------------------------------------------------------------------------

    def quickest_move(self, start: np.ndarray, end: np.ndarray, bench: int, kind: str) -> Move:
        """A cubic from start to end, as fast as the rated speeds and the accelerations allow: a
        cubic's top speed is 1.5 x delta / T and its top acceleration 6 x delta / T^2."""
        delta = np.abs(end - start)
        with np.errstate(divide="ignore", invalid="ignore"):
            duration = max(MIN_MOVE, float(np.max(np.nan_to_num(1.5 * delta / self.limits.rated))),
                           float(np.max(np.sqrt(6 * delta / self.limits.acceleration))))
        duration = np.ceil(duration / self.period - 1e-9) * self.period
        return Move(start.copy(), end.copy(), float(duration), bench, kind)

    def _nominal_time(self, segment: Move | Pass) -> float:
        if isinstance(segment, Move):
            return segment.duration
        angles = np.linspace(segment.start, segment.end, 400)
        speeds = np.minimum([self.law.speed(segment, a) for a in angles], self.law.rated)
        ramp = speeds.max() / self.limits.acceleration[1]  # s: speeding up and braking take about one ramp more
        return float(np.trapezoid(1.0 / speeds, angles) * segment.direction) + ramp


def _longest_run(mask: np.ndarray) -> tuple[int, int] | None:
    """First and last index of the longest run of True in mask, or None."""
    if not mask.any():
        return None
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    starts, ends = edges[::2], edges[1::2]
    longest = int(np.argmax(ends - starts))
    return int(starts[longest]), int(ends[longest] - 1)
