"""The closed loop for many runs at once: trajectory -> encoders -> controller -> plant, one
control period at a time, every signal a (runs, 3) array.

A lockstep is a group of runs of one machine, path, controller (and rule base) and timing; what may differ
between its runs (seeds, gains, input scales, encoders, disturbances, friction loss, wind) is
per-run data. `lockstep_key` says which runs may share a lockstep. A single run is a lockstep of
one: `simulate(scene)` is `simulate_lockstep([scene])[0]`, and a run's result does not depend
on which runs share its lockstep.

`Lockstep` is the loop without its controller, for whoever drives the drives: the scene's
controller (`simulate_lockstep`), a learning agent (`bwr_twin.gym`) or a PLC over OPC UA
(`bwr_twin.serve`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.control.interface import ControllerContext, shared_settings
from bwr_twin.control.rate import RateSignals, rate_control_class
from bwr_twin.control.registry import controller_class
from bwr_twin.errors import BwrError, EnvelopeError, SimulationError, UnreachableError
from bwr_twin.model.machine import Machine
from bwr_twin.planning.bench import plan_scene
from bwr_twin.planning.follower import BenchReference, PathReference, Phase
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.results.metrics import OnlineMetrics
from bwr_twin.results.record import Recorder, RunResult
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.plant import Plant, mujoco_warnings
from bwr_twin.stockpile.reclaim import Reclaim
from bwr_twin.stockpile.surface import build_surface

HEALTH_CHECK_EVERY = 100  # control periods between checks for divergence, and progress reports

Progress = Callable[[float, float], None]


def lockstep_key(scene: Scene) -> tuple:
    """What the runs of one lockstep share: the compiled models, the path, the controller and
    its settings other than numbers (a rule base, say), the timing, the stockpile. A bench
    reclaim ends when its own rate loop has carried out its plan, so each is a lockstep of its
    own (the scene itself is its key): no run's end waits for another's."""
    if scene.reclaim is not None:
        return ("bench reclaim", scene)
    sim = scene.simulation
    return (
        str(scene.machine.mjcf),
        scene.plant.payload,
        str(scene.controller_mjcf),
        scene.trajectory,
        scene.controller.type,
        shared_settings(scene.controller.settings),
        sim.timestep,
        sim.control_period,
        sim.record_period,
        scene.stockpile,
    )


def simulate(scene: Scene, *, progress: Progress | None = None, nthread: int = 0,
             pile_frame_period: float | None = None) -> RunResult:
    """Run one scene headless. Raises BwrError subclasses on bad input or divergence.

    `progress(done, total)`, if given, hears how many of the path's seconds are simulated, about
    once a simulated second (for a bench reclaim, of the most it may take). `pile_frame_period`
    (s), if given, keeps the pile as it is dug that often, for a replay.
    """
    (result,) = simulate_lockstep([scene], progress=progress, nthread=nthread, pile_frame_period=pile_frame_period)
    if isinstance(result, BwrError):
        raise result
    return result


def simulate_grouped(scenes: Sequence[Scene], *, nthread: int = 0) -> list[RunResult | SimulationError]:
    """Run scenes in as few locksteps as their `lockstep_key`s allow (seeds of a path scene
    together, bench reclaims one by one); results in the scenes' order."""
    groups: dict[tuple, list[int]] = {}
    for i, scene in enumerate(scenes):
        groups.setdefault(lockstep_key(scene), []).append(i)
    results: list = [None] * len(scenes)
    for members in groups.values():
        for i, result in zip(members, simulate_lockstep([scenes[i] for i in members], nthread=nthread)):
            results[i] = result
    return results


def simulate_lockstep(
    scenes: Sequence[Scene], *, progress: Progress | None = None, nthread: int = 0,
    pile_frame_period: float | None = None,
) -> list[RunResult | SimulationError]:
    """Run scenes that share a `lockstep_key` together under their controller, on `nthread`
    threads (0: all cores; never more threads than runs).

    Returns one RunResult per scene, in order, or the SimulationError of a run that diverged
    (the others go on). Raises BwrError if the path or a model is bad: that fails every run.
    """
    loop = Lockstep(scenes, nthread=nthread, pile_frame_period=pile_frame_period)
    controller = controller_class(scenes[0].controller.type)(
        loop.controller_context(), [s.controller.settings for s in scenes]
    )
    with mujoco_warnings():
        while not loop.done:
            q_measured, qd_measured = loop.measure()
            q_ref, qd_ref, qdd_ref = loop.reference_now()
            command = controller.compute(q_measured, qd_measured, q_ref, qd_ref, qdd_ref, loop.alive)
            loop.advance(command, fuzzy_output=controller.fuzzy_output,
                         acceleration_command=controller.acceleration_command)
            if progress is not None and loop.k % HEALTH_CHECK_EVERY == 0:
                progress(loop.k * loop.period, loop.duration)
    return loop.results()


class Lockstep:
    """The runs of one lockstep, advanced a control period at a time by whoever computes the
    drive forces.

    Each period k: `measure()` gives the encoders' reading, `reference_now()` the reference
    and `advance(command)` holds the drive forces for the period. After the last period
    (`done`), `results()` gives each run's result.

    The reference is a via-point path sampled in advance, the same for every run, or a bench
    reclaim (scene [reclaim]) that each run follows on its own as its rate control trims the
    slew speed; such a lockstep ends when every run has finished its plan.

    Attributes:
        machine: the plant's machine; `belief_machine` the controller's.
        reference: the runs' reference (bwr_twin.planning.follower).
        trajectory, q_desired, qd_desired, qdd_desired: a path scene's path and its (samples, 3)
            rows; `plan` and `rate_control` instead for a bench reclaim.
        time: the (samples,) times of the control periods (s); `samples` their count (for a
            bench reclaim, the most it may take until it ends).
        k: the control period about to be measured and advanced.
        plant: the MuJoCo batch's owner (the true state: `plant.qpos`, `plant.qvel`).
        reclaim: the piles being dug and their accounting, or None if the scene has no stockpile.
    """

    def __init__(self, scenes: Sequence[Scene], *, nthread: int = 0, pile_frame_period: float | None = None):
        """Raises BwrError if the path, a model or the stockpile is bad. `pile_frame_period` (s):
        keep the pile as it is dug that often, for a replay."""
        if len({lockstep_key(s) for s in scenes}) != 1:
            raise ValueError("the scenes of a lockstep must share their lockstep_key")
        self.scenes = list(scenes)
        scene = scenes[0]
        surface = build_surface(scene.stockpile, scene.path) if scene.stockpile is not None else None
        self.machine = machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload, stockpile=surface)
        self.belief_machine = Machine(scene.controller_mjcf)  # its own compiled model, even from the same file
        self.runs = runs = len(scenes)
        self.nthread = min(nthread or os.cpu_count() or 1, runs)
        self.period = period = scene.simulation.control_period
        self.plan = None
        self.rate_control = None
        if scene.reclaim is None:
            try:
                trajectory = Trajectory.plan(scene.trajectory, machine)
            except (UnreachableError, EnvelopeError) as exc:
                raise type(exc)(f"{scene.path}: {exc}") from None
            self.reference = PathReference(trajectory, period)
            self.trajectory = trajectory
            self.q_desired = self.reference.q_desired  # the path's rows, the same for every run
            self.qd_desired, self.qdd_desired = self.reference.qd_desired, self.reference.qdd_desired
        else:
            self.plan = plan_scene(scene)
            self.reference = BenchReference(self.plan, runs, period, machine.fk)
            control = scene.reclaim.rate_control
            self.rate_control = rate_control_class(control.type)(
                control, np.array([s.reclaim.target_rate for s in scenes]), period, self.scenes)
        self.samples = samples = self.reference.samples  # for a bench plan, the most it may take
        self.time = self.reference.time

        self.plant = Plant(machine, scenes, q0=self.reference.start, nthread=self.nthread)
        self._encoders = Encoders([s.encoders for s in scenes], period, self.reference.start)
        self._disturbances = Disturbances(scenes, period)
        self._recorder = Recorder(samples, round(scene.simulation.record_period / period), runs)
        self._metrics = OnlineMetrics(runs, machine.drive_limits, machine.envelope, machine.joint_range, period)
        self.reclaim = None
        if surface is not None:
            frame_every = max(round(pile_frame_period / period), 1) if pile_frame_period else None
            self.reclaim = Reclaim(scenes, machine, surface, period, len(self._recorder.samples), frame_every,
                                   plan=self.plan)
        self._wind_mean = np.array([s.plant.wind_speed for s in scenes])
        self._unrecorded = np.full((runs, 3), np.nan)  # what a controller does not compute
        self._errors_and_forces = np.zeros((runs, 12))
        self._columns = {name: self._errors_and_forces[:, getattr(OnlineMetrics, name)]
                         for name in ("POSITION", "VELOCITY", "ACCELERATION", "FORCE")}
        self._qdd, self._qd_mean = np.zeros((runs, 3)), np.zeros((runs, 3))
        self._q, self._qd, self._q_last, self._qd_last = (np.zeros((runs, 3)) for _ in range(4))
        self._inputs: tuple = ()
        self._measured: tuple = ()
        self.k = 0

    @property
    def done(self) -> bool:
        return self.k >= self.samples

    @property
    def duration(self) -> float:
        """s from the first control period to the last (for a bench reclaim, the most it may take)."""
        return (self.samples - 1) * self.period

    def reference_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Period k's reference: position, velocity, acceleration, (3,) for every run or (runs, 3)."""
        r = self.reference
        return r.q, r.qd, r.qdd

    @property
    def alive(self) -> np.ndarray | None:
        """Indices of the runs still stepped; None: all."""
        return self.plant.alive

    def controller_context(self) -> ControllerContext:
        """What a controller of these runs may know: the belief machine, never the plant."""
        return ControllerContext(self.runs, self.period, self.belief_machine, self.nthread)

    def measure(self) -> tuple[np.ndarray, np.ndarray]:
        """The encoders' (runs, 3) positions and velocities at the start of period k; once a period."""
        # This period's buffers; the last period's kept for its metrics.
        self._q, self._q_last, self._qd, self._qd_last = self._q_last, self._q, self._qd_last, self._qd
        np.copyto(self._q, self.plant.qpos)
        np.copyto(self._qd, self.plant.qvel)
        if 0 < self.k < self.samples:  # the last period's sample is finished by advance()
            self._finish(self.k - 1, self._q_last, self._qd_last, self._qd)
        self._measured = self._encoders.measure(self._q, self._qd)
        return self._measured

    def advance(self, command: np.ndarray, *, fuzzy_output: np.ndarray | None = None,
                acceleration_command: np.ndarray | None = None) -> None:
        """Hold the (runs, 3) drive forces (N, N m) over period k, with the period's disturbances.

        `fuzzy_output` and `acceleration_command`, if the controller has them, are recorded.
        """
        k = self.k
        q_measured, qd_measured = self._measured
        reference = self.reference
        disturbance = self._disturbances.forces.sample(k)
        phase = reference.phase() if self.plan is not None else None
        load = self.reclaim.step(k, self._q, self.plant.alive, phase) if self.reclaim is not None else None
        if load is not None:
            disturbance = disturbance + load
        gust = self._disturbances.gusts.sample(k)
        self.plant.step(command, disturbance, gust)
        # A bench reference changes in place: the record keeps this period's.
        planned = (reference.q, reference.qd, reference.qdd) if self.plan is None else \
            (reference.q.copy(), reference.qd.copy(), reference.qdd.copy())
        self._inputs = (q_measured, qd_measured, command, disturbance, gust,
                        _or(fuzzy_output, self._unrecorded), _or(acceleration_command, self._unrecorded), *planned)
        self.k = k = k + 1
        if self.plan is not None:
            self._follow_plan(k, phase)
        else:
            reference.advance()
        if k % HEALTH_CHECK_EVERY == 0:
            self.plant.check_health()
        if k == self.samples:
            if self.reclaim is not None:
                self.reclaim.finish(k - 1)
            self._finish(k - 1, self._q, self._qd, self.plant.qvel)
            self.plant.check_health()

    def _follow_plan(self, k: int, phase: Phase) -> None:
        """On along the bench plan to period k: the rate control's trims from what it measured in
        the period just ended, the stop condition, and the end of the lockstep once every run rests."""
        reclaim, stop = self.reclaim, self.scenes[0].reclaim.stop
        trim = self.rate_control.trim(RateSignals(reclaim.rate.copy(), reclaim.power.copy(), phase.cutting,
                                                     phase.steady))
        stopping = None
        if stop.time is not None and k * self.period >= stop.time - 1e-9:
            stopping = np.ones(self.runs, dtype=bool)
        elif stop.tonnes is not None:
            stopping = reclaim.carried_tonnes() >= stop.tonnes
        self.reference.advance(trim, stopping)
        if self.reference.finished.all() and k < self.samples:
            self.samples = k + 1  # one more period at rest, measured and recorded
            self.time = self.time[: self.samples]
            self._recorder.end_at(self.samples)

    def _finish(self, j: int, q: np.ndarray, qd: np.ndarray, qd_next: np.ndarray) -> None:
        """Sample j's metrics and record, once its period has ended at velocity qd_next."""
        columns, qdd, period = self._columns, self._qdd, self.period
        (q_measured, qd_measured, command, disturbance, gust, fuzzy_output, acceleration_command,
         q_desired, qd_desired, qdd_desired) = self._inputs
        np.subtract(q_desired, q, out=columns["POSITION"])
        np.subtract(qd_desired, qd, out=columns["VELOCITY"])
        np.divide(np.subtract(qd_next, qd, out=qdd), period, out=qdd)  # mean over the period
        np.subtract(qdd_desired, qdd, out=columns["ACCELERATION"])
        np.copyto(columns["FORCE"], self.plant.drive_force)
        np.multiply(np.add(qd, qd_next, out=self._qd_mean), 0.5, out=self._qd_mean)
        self._metrics.add(j, self._errors_and_forces, command, q, self._qd_mean)
        row = self._recorder.row(j)
        if row < 0:
            return
        self._metrics.add_cp_error(j, np.linalg.norm(self.machine.fk(q_desired) - self.machine.fk(q), axis=1))
        signals = self._recorder.signals
        for name, value in (("q_desired", q_desired), ("q", q), ("q_measured", q_measured),
                            ("qd_desired", qd_desired), ("qd", qd), ("qd_measured", qd_measured),
                            ("qdd_desired", qdd_desired), ("qdd", qdd),
                            ("fuzzy_output", fuzzy_output), ("acceleration_command", acceleration_command),
                            ("drive_force_command", command), ("drive_force", self.plant.drive_force),
                            ("disturbance", disturbance)):
            signals[name][row] = value
        self._recorder.wind_speed[row] = self._wind_mean + gust
        if self.reclaim is not None:
            self.reclaim.record(row)

    def results(self) -> list[RunResult | SimulationError]:
        """Each run's result, or the SimulationError of a run that diverged; once `done`."""
        if not self.done:
            raise RuntimeError(f"the lockstep is at control period {self.k} of {self.samples}")
        results: list[RunResult | SimulationError] = []
        for run, scene in enumerate(self.scenes):
            if run in self.plant.failures:
                results.append(SimulationError(
                    f"{scene.path}: the simulation diverged ({self.plant.failures[run]}); try smaller gains or timestep"
                ))
                continue
            metrics = self._metrics.result(run, self.time)
            if self.reclaim is not None:
                metrics["reclaim"] = self.reclaim.metrics(run)
            metrics["run"] = {
                "scene": str(scene.path),
                "mjcf": str(scene.machine.mjcf),
                "controller_mjcf": str(scene.controller_mjcf),
                "seed": scene.simulation.seed,
                "duration": self.duration,
                "control_period": self.period,
                "timestep": scene.simulation.timestep,
            }
            waypoints, names = self.reference.waypoints(run)
            if self.plan is not None:  # where the run began each segment of its plan, for a replay
                metrics["run"]["waypoint_times"] = waypoints.times.tolist()
                metrics["run"]["waypoints"] = waypoints.points.tolist()
                metrics["run"]["waypoint_names"] = names
            result = self._recorder.run_result(run, scene=scene, machine=self.machine,
                                               trajectory=waypoints, time=self.time,
                                               metrics=metrics)
            if self.reclaim is not None:
                result.reclaim = self.reclaim.run_record(run, self._recorder.rows)
            results.append(result)
        return results


def _or(signal: np.ndarray | None, missing: np.ndarray) -> np.ndarray:
    return missing if signal is None else signal
