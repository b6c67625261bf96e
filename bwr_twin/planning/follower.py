"""References for a lockstep's runs, one control period at a time.

`PathReference` is a scene's via-point path, sampled once for every run. `BenchReference`
follows a bench plan (bwr_twin.planning.bench) for each run on its own: moves are sampled from
their cubics; a slew pass's speed is decided every period from the speed law times the run's rate
trim, reached and left within the slew acceleration and the rated speed, and braked to rest
exactly at the pass's end. The slew reference's acceleration is constant over a period, so its
position, velocity and acceleration agree exactly.

Every run is followed every control period, so a period's arithmetic is `math` on Python
floats, read from and written to the (runs, 3) arrays one value at a time: numpy on scalars
costs a microsecond an operation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bwr_twin.planning.plan import BenchPlan, Move, Pass
from bwr_twin.planning.trajectory import Trajectory, rest_to_rest

SLEW = 1
END_TOLERANCE = 1e-9  # rad short of a pass's end that always counts as there (55 nm at 55 m)


@dataclass(frozen=True)
class Phase:
    """Where each run stands in a bench plan this control period; (runs,) arrays."""

    bench: np.ndarray  # 0-based
    cutting: np.ndarray  # bool: in a slew pass, within its predicted cut
    steady: np.ndarray  # bool: in a slew pass, where its face stands at its full section
    planned_depth: np.ndarray  # m across the face the pass plans to cut here (nan outside a pass)


class PathReference:
    """The via-point path, the same for every run: `q`, `qd`, `qdd` are (3,) rows of period k."""

    def __init__(self, trajectory: Trajectory, period: float,
                 rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None):
        """`rows`: the path's own (samples, 3) positions, velocities and accelerations at the
        control period, where `trajectory` holds only its waypoints (a stacking pattern's,
        bwr_twin.planning.stacking); None samples the trajectory."""
        self.trajectory = trajectory
        self.samples = round(trajectory.duration / period) + 1 if rows is None else len(rows[0])
        self.time = trajectory.times[0] + np.arange(self.samples) * period
        self.q_desired, self.qd_desired, self.qdd_desired = trajectory.sample(self.time) if rows is None else rows
        self.start = self.q_desired[0]
        self.finished = False
        self.k = 0

    @property
    def q(self) -> np.ndarray:
        return self.q_desired[self.k]

    @property
    def qd(self) -> np.ndarray:
        return self.qd_desired[self.k]

    @property
    def qdd(self) -> np.ndarray:
        return self.qdd_desired[self.k]

    def advance(self, trim: np.ndarray | None = None, stop: np.ndarray | None = None) -> None:
        self.k += 1

    def waypoints(self, run: int) -> tuple[Trajectory, list[str]]:
        return self.trajectory, [f"P{i + 1}" for i in range(len(self.trajectory.times))]


class BenchReference:
    """Each run's place in a bench plan and its reference for the current control period.

    Attributes:
        q, qd, qdd: (runs, 3) the reference of the current period (m, rad; /s; /s^2).
        segment: (runs,) index into plan.segments; len(segments) once a run is finished.
        bench: (runs,) 0-based bench of each run's segment (its last once finished).
        finished: (runs,) bool: the run has completed its plan (or stopped) and rests.
    """

    def __init__(self, plan: BenchPlan, runs: int, period: float, fk: Callable[[np.ndarray], np.ndarray]):
        """`fk` maps joint values to the CP, for the waypoints."""
        self._plan = _PlanInFloats(plan)
        self.runs, self.period = runs, period
        self.samples = int(np.ceil(plan.longest_duration / period - 1e-9)) + 1
        self.time = np.arange(self.samples) * period
        self.q = np.repeat(plan.start[None], runs, axis=0)
        self.qd = np.zeros((runs, 3))
        self.qdd = np.zeros((runs, 3))
        self.segment = np.zeros(runs, dtype=np.int64)
        self.bench = np.full(runs, plan.segments[0].bench, dtype=np.int64)
        self.finished = np.zeros(runs, dtype=bool)
        self.k = 0
        self._elapsed = [0.0] * runs  # s into the current move
        self._orders = Orders(runs)
        self._log = SegmentLog(plan, runs, fk)
        for run in range(runs):
            self._plan_period(run)

    @property
    def plan(self) -> BenchPlan:
        return self._plan.plan

    @property
    def start(self) -> np.ndarray:
        """(3,) where every run starts: the start of the plan it was made with."""
        return self._plan.start

    @property
    def stopping(self) -> np.ndarray:
        """(runs,) bool: the runs told to end their plan."""
        return self._orders.stopping

    def phase(self) -> Phase:
        """Where every run stands in its plan this period."""
        cutting, steady, depth = [False] * self.runs, [False] * self.runs, [math.nan] * self.runs
        for run in range(self.runs):
            p = self.current_pass(run)
            if p is None:
                continue
            slew = self.q.item(run, SLEW)
            cutting[run], steady[run] = p.cuts_at(slew), p.steady_at(slew)
            depth[run] = p.cut_depth * abs(math.cos(slew))
        return Phase(self.bench.copy(), np.array(cutting, dtype=bool), np.array(steady, dtype=bool),
                     np.array(depth, dtype=float))

    def continue_with(self, plan: BenchPlan) -> None:
        """Every run has finished the plan it followed (a survey) and rests: go on with `plan`,
        whose segments begin with that plan's. `samples` grows by the most the new segments may take."""
        first = len(self.plan.segments)
        self._plan.extend(plan, first)
        stage = segment_stage(plan, first)
        for run in range(self.runs):
            self.finished[run] = False
            self.segment[run] = first
            self.bench[run] = plan.segments[first].bench
            self._elapsed[run] = 0.0
            self._log.rename_last(run, stage)
            self._plan_period(run)
        before = sum(segment.duration for segment in plan.segments[:first])  # moves alone
        self.samples = self.k + int(np.ceil((plan.longest_duration - before) / self.period - 1e-9)) + 1
        self.time = np.arange(self.samples) * self.period

    def current_pass(self, run: int) -> Pass | None:
        if self.finished[run]:
            return None
        segment = self.plan.segments[self.segment[run]]
        return segment if isinstance(segment, Pass) else None

    def advance(self, trim: np.ndarray | None = None, stop: np.ndarray | None = None,
                pace: np.ndarray | None = None) -> None:
        """Move every run on by one control period; `trim` (runs,) scales the speed law from now
        on, `stop` (runs,) bool ends a run's plan: a pass brakes to rest, a move is completed;
        `pace` (runs,) in [0, 1], an interlock's, slows the plan: a move's time runs at it (its
        velocity and acceleration scaled), a pass's speed law is scaled by it and braked to."""
        orders = self._orders
        orders.take(trim, stop, pace)
        self.k += 1
        dt = self.period
        for run in range(self.runs):
            if self.finished[run]:
                continue
            index = self.segment.item(run)
            segment = self.plan.segments[index]
            if isinstance(segment, Move):
                self._elapsed[run] += dt * orders.pace[run]
                if self._elapsed[run] >= segment.duration - 1e-9:
                    self._next(run, segment.end)
            else:
                q, qd, qdd = self.q.item(run, SLEW), self.qd.item(run, SLEW), self.qdd.item(run, SLEW)
                slew = q + qd * dt + 0.5 * qdd * dt**2
                speed = qd + qdd * dt
                self.q[run, SLEW], self.qd[run, SLEW] = slew, speed
                stopping = orders.stopping.item(run)
                there = (segment.end - slew) * segment.direction <= END_TOLERANCE  # never past it
                if there or (stopping and speed == 0.0):
                    self.q[run, SLEW] = segment.end if not stopping else slew
                    self._next(run, self.q[run].copy())
            if not self.finished[run]:
                self._plan_period(run)

    def _next(self, run: int, at: np.ndarray) -> None:
        """Run `run` has completed its segment at joint values `at`: on to the next, or rest."""
        self.segment[run] += 1
        self._elapsed[run] = 0.0
        self.q[run] = at
        self.qd[run] = 0.0
        self.qdd[run] = 0.0
        if self.segment[run] >= len(self.plan.segments) or self.stopping[run]:
            self.finished[run] = True
            self.segment[run] = len(self.plan.segments)
        else:
            self.bench[run] = self.plan.segments[self.segment[run]].bench
        self._log.begin(run, self.k * self.period, at, segment_stage(self.plan, self.segment[run]))

    def _plan_period(self, run: int) -> None:
        """The reference of the current period for run `run`, within its segment."""
        index, plan, orders = self.segment.item(run), self._plan, self._orders
        segment = plan.plan.segments[index]
        if isinstance(segment, Move):
            start, end = plan.ends[index]
            s = min(max(self._elapsed[run] / segment.duration, 0.0), 1.0)  # as Move.sample
            q, qd, qdd = self.q, self.qd, self.qdd
            pace = orders.pace[run]
            for j in range(3):
                q[run, j], qd[run, j], qdd[run, j] = rest_to_rest(start[j], end[j], segment.duration, s)
                if pace != 1.0:
                    qd[run, j] *= pace
                    qdd[run, j] *= pace * pace
            return
        slew, speed = self.q.item(run, SLEW), self.qd.item(run, SLEW)
        direction, a, dt = segment.direction, plan.slew_acceleration, self.period
        stopping = orders.stopping.item(run)
        if stopping:
            wanted = 0.0
        else:
            remaining = max((segment.end - slew) * direction, 0.0)
            law = plan.plan.law.speed(segment, slew) * orders.trim[run] * orders.pace[run]
            # The fastest speed v at the period's end from which braking by a dt a period still
            # stops at the pass's end: this period's (|qd| + v) dt / 2 and then at most
            # v^2 / 2a + v dt / 2 of braking fit in what remains.
            rest = remaining - 0.5 * abs(speed) * dt
            brake = math.sqrt((a * dt) ** 2 + 2.0 * a * max(rest, 0.0)) - a * dt
            wanted = min(law, plan.top_speed, brake)
            # Land on the end: never step past it within this period.
            wanted = min(wanted, 2.0 * remaining / dt - abs(speed))
            wanted = max(wanted, 0.0)
        change = min(max(direction * wanted - speed, -a * dt), a * dt)
        if stopping and abs(speed) <= a * dt:
            change = -speed
        # Travel and luff rest through a pass: _next left their qdd at 0.
        self.qdd[run, SLEW] = change / dt

    def waypoints(self, run: int) -> tuple[Trajectory, list[Stage]]:
        """Where run `run` began each segment (and where it ended), its reclaim as via points,
        and their stages (`segment_stage`)."""
        now = None if self.finished[run] else (self.k * self.period, self.q[run].copy())
        return self._log.waypoints(run, now)


class _PlanInFloats:
    """The bench plan as a period's arithmetic reads it: each move's ends and the slew's limits as
    Python floats (numpy on scalars costs a microsecond an operation)."""

    def __init__(self, plan: BenchPlan):
        self.plan, self.start = plan, plan.start
        # each move's ends as Python floats, by segment index
        self.ends = {i: (s.start.tolist(), s.end.tolist()) for i, s in enumerate(plan.segments) if isinstance(s, Move)}
        self.slew_acceleration = float(plan.acceleration[SLEW])
        self.top_speed = float(plan.rated_speed[SLEW])

    def extend(self, plan: BenchPlan, first: int) -> None:
        """Go on with `plan`, whose segments before `first` are this plan's."""
        self.plan = plan
        self.ends.update({i: (s.start.tolist(), s.end.tolist()) for i, s in enumerate(plan.segments)
                          if isinstance(s, Move) and i >= first})


class Orders:
    """What the loop asks of each run's reference: the rate trim on the speed law, an
    interlock's pace (the share of its pace each run follows its plan at) and whether to stop."""

    def __init__(self, runs: int):
        self.trim = [1.0] * runs
        self.pace = [1.0] * runs
        self.stopping = np.zeros(runs, dtype=bool)

    def take(self, trim: np.ndarray | None, stop: np.ndarray | None, pace: np.ndarray | None) -> None:
        """From now on: `trim` and `pace` (runs,) where given; `stop` (runs,) bool adds to the stopping."""
        if trim is not None:
            self.trim = np.asarray(trim, dtype=float).tolist()
        if pace is not None:
            self.pace = np.asarray(pace, dtype=float).tolist()
        if stop is not None:
            self.stopping |= stop


class SegmentLog:
    """Where each run began each segment of its plan, and its stage: the via points a replay shows."""

    def __init__(self, plan: BenchPlan, runs: int, fk: Callable[[np.ndarray], np.ndarray]):
        """`fk` maps joint values to the CP, for the waypoints."""
        self._fk = fk
        # (time, q, stage) at each segment's start, and at the end
        self._started = [[(0.0, plan.start.copy(), segment_stage(plan, 0))] for _ in range(runs)]

    def begin(self, run: int, time: float, at: np.ndarray, stage: Stage) -> None:
        self._started[run].append((time, at.copy(), stage))

    def rename_last(self, run: int, stage: Stage) -> None:
        """The run's last segment start begins `stage` instead (a plan continued from its end)."""
        time, at, _ = self._started[run][-1]
        self._started[run][-1] = (time, at, stage)

    def waypoints(self, run: int, now: tuple[float, np.ndarray] | None) -> tuple[Trajectory, list[Stage]]:
        """The run's segment starts as via points and their stages; `now` (time, q), if the run
        goes on, ends them at the "end" stage."""
        started = list(self._started[run])
        if now is not None:
            started.append((*now, Stage("end")))
        times = np.array([t for t, _, _ in started])
        knots = np.array([q for _, q, _ in started])
        # A zero-length segment adds no point; a named stage wins over a move at the same time.
        keep = np.append(np.diff(times) > 0, True)
        stages = [started[i][2] if started[i][2].kind != "move" or not i or keep[i - 1] else started[i - 1][2]
                  for i in range(len(started))]
        return (Trajectory(times=times[keep], knots=knots[keep], points=self._fk(knots[keep])),
                [stage for stage, kept in zip(stages, keep) if kept])


@dataclass(frozen=True)
class Stage:
    """Where a segment of a bench plan starts, typed: "survey" where a survey's move does, "bench"
    where a bench's moves begin, "pass" where a pass does (`number` is the bench, 1-based, or the
    pass's number), "move" for a travel step or a step down, "end" after the last."""

    kind: Literal["survey", "bench", "pass", "move", "end"]
    number: int | None = None

    @property
    def name(self) -> str:
        """What a replay labels it: "bench 2", "pass 7", "end"; "" for a move."""
        return "" if self.kind == "move" else self.kind if self.number is None else f"{self.kind} {self.number}"

    def to_dict(self) -> dict:
        return {"kind": self.kind, "number": self.number}


def segment_stage(plan: BenchPlan, index: int) -> Stage:
    """The stage at the start of segment `index` of `plan`."""
    if index >= len(plan.segments):
        return Stage("end")
    segment = plan.segments[index]
    if isinstance(segment, Pass):
        return Stage("pass", segment.number)
    if segment.kind == "survey":
        return Stage("survey")
    return Stage("bench", segment.bench + 1) if segment.kind in ("approach", "slew clear") else Stage("move")


def nominal(plan: BenchPlan, period: float, fk: Callable[[np.ndarray], np.ndarray], every: int = 1,
            stop_time: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, Trajectory, list[Stage]]:
    """The plan followed open loop (no trim) by one run: times (n,), q and qd (n, 3) every `every`
    control periods, its waypoints and their stages; what a replay shows before the run is simulated."""
    reference = BenchReference(plan, 1, period, fk)
    stop = np.ones(1, dtype=bool)
    rows = []
    while True:
        if reference.k % every == 0 or reference.finished[0]:
            rows.append((reference.k * period, reference.q[0].copy(), reference.qd[0].copy()))
        if reference.finished[0] or reference.k >= reference.samples - 1:
            break
        halt = stop_time is not None and (reference.k + 1) * period >= stop_time - 1e-9
        reference.advance(None, stop if halt else None)
    time = np.array([t for t, _, _ in rows])
    return (time, np.array([q for _, q, _ in rows]), np.array([v for _, _, v in rows]), *reference.waypoints(0))
