"""What the runs of a lockstep follow: one protocol, two kinds.

`PathTracking` is a scene's via-point path, sampled once at the control period and the same for
every run; `StackingTracking` a stacking pattern, followed the same way. `BenchTracking` is a bench reclaim (scene [reclaim]) that each run follows on its own:
its rate control trims the slew speed from what the run's reclaim measured in the period just
ended, its stop condition ends the plan, and the lockstep ends once every run rests.

Both give the current period's reference (`now`), where each run stands in its plan (`phase`),
move on a period (`advance`) and say where each run began each segment (`waypoints`). A bench
plan re-plans itself as its survey of the pile ends; the loop only sees `samples` change.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from bwr_twin.config.plugin_calls import call, checked, construct, describe
from bwr_twin.config.plugins import rate_control_class
from bwr_twin.config.scene import Scene
from bwr_twin.control.rate import RateSignals, WheelCalibration
from bwr_twin.errors import EnvelopeError, PluginError, UnreachableError
from bwr_twin.model.machine import Machine
from bwr_twin.planning.bench import plan_after_survey, plan_scene, survey_plan
from bwr_twin.planning.follower import BenchReference, PathReference, Phase
from bwr_twin.planning.stacking import plan_stacking
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.sensing.rate_instruments import RateInstruments
from bwr_twin.sim.outcome import PlanOutcome
from bwr_twin.stockpile.reclaim import Reclaim


class PathTracking:
    """The via-point path of a scene: (3,) rows of period k, shared by every run.

    Attributes:
        rows: the path's (samples, 3) positions, velocities and accelerations.
        samples, time: the control periods and their (samples,) times (s).
        start: (3,) the joint values the runs start at.
        paced: None, or an interlock's guard (bwr_twin.collision.guard) whose (runs, 3)
            reference follows the path at the pace it decides (`pace_by`).
    """

    shared = True
    plan = None
    survey_end = None
    paced = None

    def __init__(self, scene: Scene, machine: Machine, period: float):
        """Raises UnreachableError or EnvelopeError, naming the scene, for a path the machine cannot follow."""
        try:
            trajectory = Trajectory.plan(scene.trajectory, machine)
        except (UnreachableError, EnvelopeError) as exc:
            raise type(exc)(f"{scene.path}: {exc}") from None
        self._follow(PathReference(trajectory, period))

    def _follow(self, reference: PathReference) -> None:
        self._reference = reference
        self.trajectory = reference.trajectory
        self.rows = (reference.q_desired, reference.qd_desired, reference.qdd_desired)
        self.samples, self.time, self.start = reference.samples, reference.time, reference.start

    def pace_by(self, guard) -> None:
        """Follow the path at the pace `guard` decides: each run's own reference from then on."""
        self.paced = guard

    @property
    def own_rows(self) -> bool:
        """Whether the runs' references differ, so that the record keeps each run's."""
        return self.paced is not None

    def now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self._reference if self.paced is None else self.paced
        return r.q, r.qd, r.qdd

    def phase(self) -> None:
        return None

    def advance(self, k: int, phase: None) -> None:
        """On to period k; a path never ends early."""
        self._reference.advance()

    def waypoints(self, run: int) -> tuple[Trajectory, list[str]]:
        return self._reference.waypoints(run)

    def run_metrics(self, run: int) -> dict:
        return {}

    def reclaim_metrics(self, run: int) -> dict:
        return {}

    def finish(self) -> None:
        pass


class StackingTracking(PathTracking):
    """A stacking pattern (scene [stacking], bwr_twin.planning.stacking), planned once and the
    same for every run, followed as a path is.

    Attributes:
        pattern: the StackingPlan: its passes, crests and the pile's grid.
    """

    def __init__(self, scene: Scene, machine: Machine, period: float):
        self.pattern = pattern = plan_stacking(scene, machine, period)
        self._follow(PathReference(pattern.waypoints, period, pattern.rows))

    def run_metrics(self, run: int) -> dict:
        """Where each pass began and ended, and which, for a replay."""
        waypoints = self.pattern.waypoints
        return {"waypoint_times": waypoints.times.tolist(), "waypoints": waypoints.points.tolist(),
                "waypoint_names": [stage.name for stage in self.pattern.stages],
                "waypoint_stages": [stage.to_dict() for stage in self.pattern.stages]}


class BenchTracking:
    """A bench plan, followed by every run on its own: (runs, 3) references.

    Attributes:
        plan: the bench plan (bwr_twin.planning.plan.BenchPlan).
        samples, time: the most control periods the plan may take (once every run rests, those
            it took), and their times (s).
        start: (3,) the plan's start.
        external_trim: None while the scene's rate control trims the slew speed; else the trim
            every run takes from the next period on, set by a rate loop outside the twin (the
            FMU's importer), held within the scene's `trim_limits`.
        pace: None, or an interlock's (runs,) pace along the plan in [0, 1], from the next
            period on (bwr_twin.collision.guard).
    """

    shared = False
    own_rows = True
    external_trim: float | None = None
    pace: np.ndarray | None = None  # an interlock's (runs,) pace along the plan, from the next period on

    def __init__(self, scenes: Sequence[Scene], machine: Machine, period: float, reclaim: Reclaim, *,
                 known_pile: Callable[[], np.ndarray] | None = None, instruments: RateInstruments | None = None):
        """`reclaim`: the runs' piles and belts, whose rates the rate control and the stop
        condition read. `known_pile()`, if given, is the pile the runs know from their scans, (ny, nx) m: the
        benches are planned on it as the [reclaim.survey] ends, not on the true pile in advance.
        Runs of one lockstep share their scene and seed, so their scans and plans are the same.
        `instruments`, if given, are what the rate control reads instead of the true rate and
        power. Raises BwrError for a plan that cannot be carried out (bwr_twin.planning.bench)."""
        scene = scenes[0]
        self._reclaim = reclaim
        survey = survey_plan(scene)
        # The control period at which the survey ends and the benches begin; None without a survey.
        self.survey_end = None if survey is None else round(survey.nominal_duration / period)
        # What plans the benches on the pile the runs know as the survey ends; None once planned,
        # or where they were planned in advance on the true pile.
        self._benches = (None if known_pile is None or survey is None
                         else lambda: plan_after_survey(scene, machine, known_pile()))
        self.plan = plan_scene(scene) if self._benches is None else survey
        self._reference = reference = BenchReference(self.plan, len(scenes), period, machine.fk)
        if scene.interlock is not None:  # slowed, the plan may take as long again over the slow share
            reference.samples = math.ceil(reference.samples / scene.interlock.slow_share)
            reference.time = np.arange(reference.samples) * period
        self.samples = reference.samples
        self._period = period
        self._stop = scene.reclaim.stop
        self._trim = SlewTrim(scenes, period, instruments)
        self._bucket_interval = machine.wheel.bucket_interval
        self.outcome = PlanOutcome(self.plan, self._trim.targets, self._bucket_interval, period)

    @property
    def time(self) -> np.ndarray:
        return self._reference.time

    @property
    def start(self) -> np.ndarray:
        return self._reference.start

    @property
    def instruments(self) -> RateInstruments | None:
        """What the rate control reads instead of the true rate and power, if given."""
        return self._trim.instruments

    def now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self._reference
        return r.q, r.qd, r.qdd

    def phase(self) -> Phase:
        return self._reference.phase()

    def advance(self, k: int, phase: Phase) -> None:
        """On to period k from the period just ended, where the runs stood at `phase`: the rate
        control's trims from what each run's reclaim measured in it, the stop condition. Once
        every run rests, `samples` shrinks to the periods the lockstep takes in all (one more at
        rest, measured and recorded). As a survey on the scanned pile ends, the benches are
        planned and `samples` grows to the most they may take."""
        reference, reclaim = self._reference, self._reclaim
        if self._benches is None:
            self.outcome.add(k - 1, phase, reclaim)
        trim = self._trim.trims((k - 1) * self._period, reclaim, phase, self.external_trim)
        stop, stopping = self._stop, None
        if stop.time is not None and k * self._period >= stop.time - 1e-9:
            stopping = np.ones(len(trim), dtype=bool)
        elif stop.tonnes is not None:
            stopping = reclaim.carried_tonnes() >= stop.tonnes
        reference.advance(trim, stopping, self.pace)
        if not all(reference.finished.tolist()):  # per period: a list, not an array reduction (µs)
            return
        if self._benches is not None:
            self._plan_benches()
            return
        self.samples = min(self.samples, k + 1)

    def _plan_benches(self) -> None:
        """The survey has ended: the benches planned on the pile the runs know, followed from here."""
        self.plan = self._benches()
        self._benches = None
        self._reference.continue_with(self.plan)
        self.samples = self._reference.samples
        self.outcome = PlanOutcome(self.plan, self._trim.targets, self._bucket_interval, self._period)

    def waypoints(self, run: int) -> tuple[Trajectory, list[str]]:
        return self._reference.waypoints(run)

    def reclaim_metrics(self, run: int) -> dict:
        """How the run carried out its plan (bwr_twin.sim.outcome)."""
        return self.outcome.metrics(run, float(self._reclaim.density[run]))

    def finish(self) -> None:
        """The runs' reclaim has ended: its last discharge counts to their last bench."""
        self.outcome.discharged(self._reclaim.conveyor.discharged)

    def run_metrics(self, run: int) -> dict:
        """Where the run began each segment of its plan, and which, for a replay."""
        waypoints, stages = self._reference.waypoints(run)
        return {"waypoint_times": waypoints.times.tolist(), "waypoints": waypoints.points.tolist(),
                "waypoint_names": [stage.name for stage in stages],
                "waypoint_stages": [stage.to_dict() for stage in stages]}


class SlewTrim:
    """Each period's slew speed trims: the scene's rate control's, from what each run's reclaim
    (or its instruments) measured, or one set from outside the twin; checked within the scene's
    `trim_limits`, so that an engineer's rate control fails with its own name.

    Attributes:
        targets: (runs,) t/h each run's target rate.
        instruments: what the rate control reads instead of the true rate and power, or None.
    """

    def __init__(self, scenes: Sequence[Scene], period: float, instruments: RateInstruments | None):
        scene = scenes[0]
        self.instruments = instruments
        control = scene.reclaim.rate_control
        self._limits = control.trim_limits
        digging = [s.digging for s in scenes]
        wheel = WheelCalibration(
            idle_power=np.array([d.idle_power if d else np.nan for d in digging]),
            cutting_energy=np.array([(control.cutting_energy or d.cutting_energy) if d else np.nan for d in digging]),
            bulk_density=np.array([s.stockpile.bulk_density for s in scenes]),
            belt_delay=instruments.delay_periods * period if instruments and instruments.scale else 0.0,
        )
        self.targets = np.array([s.reclaim.target_rate for s in scenes])
        cls = rate_control_class(control.type)
        self._label = f"{scene.path}: rate control {describe(control.type, cls)}"  # an engineer's failures are theirs
        self._rate_control = construct(self._label, cls, control, self.targets, period, wheel)

    def trims(self, time: float, reclaim: Reclaim, phase: Phase, external: float | None) -> np.ndarray:
        """(runs,) the trims after the period that began at `time` (s), in which the runs stood at
        `phase`; `external`, if not None, is every run's, clipped to the limits. PluginError for a
        trim that is not finite or not within the limits."""
        instruments = self.instruments
        if instruments is None:
            signals = RateSignals(reclaim.rate.copy(), reclaim.power.copy(), phase.cutting, phase.steady)
        else:
            signals = RateSignals(instruments.belt_scale.copy(), instruments.wheel_power.copy(), phase.cutting,
                                  phase.steady, instruments.wheel_current.copy())
        if external is not None:
            trim = np.full(len(signals.belt_rate), np.clip(external, *self._limits))
        else:
            trim = checked(self._label, "trim", call(self._label, self._rate_control.trim, "trim", time, signals),
                           (len(signals.belt_rate),), time)
        low, high = self._limits  # an external trim is clipped to them; NaN lies within none
        if not all(low - 1e-9 <= t <= high + 1e-9 for t in trim.tolist()):  # per period: scalars, not array ops
            if not np.isfinite(trim).all():
                raise PluginError(f"{self._label}: trim() returned {trim} at t = {time:.2f} s; trims must be finite")
            raise PluginError(f"{self._label}: trim() returned {trim} at t = {time:.2f} s; trims must lie within "
                              f"'reclaim.rate_control.trim_limits' [{low:g}, {high:g}] (a multiple of the slew "
                              "speed law's, never negative)")
        return trim
