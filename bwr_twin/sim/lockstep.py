"""The closed loop for many runs at once, one control period at a time: encoders -> reference
-> controller -> plant, every signal a (runs, 3) array.

A lockstep is a group of runs of one machine, path, controller (and rule base) and timing; what may differ
between its runs (seeds, gains, input scales, encoders, disturbances, friction loss, wind) is
per-run data (`RunParameters`). `lockstep_key` says which runs may share a lockstep. A single
run is a lockstep of one: `simulate(scene)` is `simulate_lockstep([scene])[0]`, and a run's
result does not depend on which runs share its lockstep.

`Lockstep` only steps: whoever drives the drives (the scene's controller in `simulate_lockstep`,
a learning agent in `bwr_twin.gym`, a PLC over OPC UA in `bwr_twin.serve`) calls `measure()`,
reads `reference_now()` and calls `advance(command)`, and sees the machine only through
read-only views. Each period's raw signals go into the loop's block of rows
(`bwr_twin.sim.block`); an observer (`bwr_twin.sim.observer`) reduces each full block into the
metrics and the record. Every optional part of the world is a stage the loop walks in order
(`bwr_twin.sim.stages`); what only watches, the clearance monitors, is an observer too
(`bwr_twin.sim.watchers`).
"""

from __future__ import annotations

import functools
import types
from collections.abc import Callable, Sequence

import numba
import numpy as np

from bwr_twin.config.plugin_calls import call, checked, construct, describe
from bwr_twin.config.plugins import controller_class
from bwr_twin.config.scene import Scene
from bwr_twin.control.interface import Controller, ControllerContext, shared_settings
from bwr_twin.errors import BwrError, SimulationError
from bwr_twin.model.machine import AXES
from bwr_twin.sim.assembly import assemble
from bwr_twin.sim.block import BLOCK, Block, read_only
from bwr_twin.sim.observer import Observer
from bwr_twin.sim.plant import mujoco_warnings
from bwr_twin.sim.record import RunResult
from bwr_twin.sim.stages import Hooks

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
        scene.sensing,
        scene.faults,
        scene.interlock,
        # one neighbour's file and drives; each run follows its own schedule
        (scene.neighbour.mjcf, scene.neighbour.bandwidth, scene.neighbour.report_delay) if scene.neighbour else None,
        scene.stacking,  # one pattern and pile grid; each run's grade from its own seed
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


def simulate_grouped(scenes: Sequence[Scene], *, nthread: int = 0,
                     progress: Progress | None = None) -> list[RunResult | SimulationError]:
    """Run scenes in as few locksteps as their `lockstep_key`s allow (seeds of a path scene
    together, bench reclaims one by one); results in the scenes' order. `progress(done, total)`
    hears the simulated seconds of the locksteps so far, out of a total that counts the ones
    left as long as the current one."""
    groups: dict[tuple, list[int]] = {}
    for i, scene in enumerate(scenes):
        groups.setdefault(lockstep_key(scene), []).append(i)
    results: list = [None] * len(scenes)
    done = 0.0
    for number, members in enumerate(groups.values()):
        heard = None
        if progress is not None:
            def heard(t: float, total: float, before: float = done, left: int = len(groups) - 1 - number) -> None:
                progress(before + t, before + total * (1 + left))  # the locksteps left take as long
        loop_results = simulate_lockstep([scenes[i] for i in members], nthread=nthread, progress=heard)
        for i, result in zip(members, loop_results):
            results[i] = result
        done += max((r.metrics["run"]["duration"] for r in loop_results if isinstance(r, RunResult)), default=0.0)
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
    type_name = scenes[0].controller.type
    cls = controller_class(type_name)
    name = describe(type_name, cls)
    label = f"{scenes[0].path}: controller {name}"  # an engineer's failures are named as theirs
    controller = construct(label, cls, loop.controller_context(), [s.controller.settings for s in scenes])
    loop.record_controller(controller)
    loop.command_source = f"controller {name}: compute()"
    measure, reference_now, advance, compute = loop.measure, loop.reference_now, loop.advance, controller.compute
    shape, period = (loop.runs, 3), loop.period
    with mujoco_warnings():
        while not loop.done:
            q_measured, qd_measured = measure()
            q_ref, qd_ref, qdd_ref = reference_now()
            time = loop.k * period
            command = call(label, compute, "compute", time, q_measured, qd_measured, q_ref, qd_ref, qdd_ref,
                           loop.alive)
            advance(checked(label, "compute", command, shape, time))
            if progress is not None and loop.k % HEALTH_CHECK_EVERY == 0:
                progress(loop.k * period, loop.duration)
    return loop.results()


class Lockstep:
    """The runs of one lockstep, advanced a control period at a time by whoever computes the drive forces.

    Each period k: `measure()` gives the encoders' reading, `reference_now()` the reference
    and `advance(command)` holds the drive forces for the period. After the last period
    (`done`), `results()` gives each run's result. The loop itself only walks its stages and
    watchers (bwr_twin.sim.stages, bwr_twin.sim.watchers), built once (bwr_twin.sim.assembly).

    Attributes:
        machine: the plant's machine; `belief_machine` the controller's.
        tracking: what the runs follow (bwr_twin.sim.tracking): a path shared by every run, or a
            bench plan each run follows on its own.
        samples: the control periods the runs take (for a bench reclaim, the most they may take
            until they end); `time` their (samples,) times (s).
        k: the control period about to be measured and advanced.
        reclaim, scanning, instruments, neighbour, faults: the world models drivers may read
            (bwr_twin.sim.assembly.Parts), None where the scene has none.
    """

    def __init__(self, scenes: Sequence[Scene], *, nthread: int = 0, pile_frame_period: float | None = None,
                 observe: bool = True):
        """Raises BwrError if the path, a model or the stockpile is bad. `pile_frame_period` (s):
        keep the pile as it is dug that often, for a replay. `observe=False`: no metrics, no
        record and no watchers (a driver that keeps its own, such as a learning agent's environment)."""
        if len({lockstep_key(s) for s in scenes}) != 1:
            raise ValueError("the scenes of a lockstep must share their lockstep_key")
        self.scenes = list(scenes)
        sim = scenes[0].simulation
        self.period = period = sim.control_period
        frame_every = max(round(pile_frame_period / period), 1) if pile_frame_period else None
        self._parts = parts = assemble(scenes, nthread=nthread, frame_every=frame_every, observe=observe)
        self.machine, self.belief_machine, self.tracking = parts.machine, parts.belief_machine, parts.tracking
        self._plant = plant = parts.plant
        self.samples = self.tracking.samples
        self._hooks = Hooks.of(parts.stages)
        self._block = Block(self.runs, BLOCK if observe else 1, own_reference=self.tracking.own_rows,
                            reclaim=parts.reclaim is not None, neighbour=parts.neighbour is not None)
        self._block.q[0], self._block.qd[0] = plant.qpos, plant.qvel  # the first period's start
        self._observer = Observer(
            self.runs, self.samples, period, round(sim.record_period / period), self.machine,
            path=None if self.tracking.own_rows else self.tracking.rows, wind_mean=parts.parameters.wind_speed,
            reclaim=parts.reclaim is not None, neighbour=parts.neighbour is not None) if observe else None
        self._controller: Controller | None = None  # whose declared signals are recorded
        self.command_source = "the drive forces given"  # who computes them, for messages
        self._stopped: set[int] = set()  # runs stopped for non-finite drive forces
        self.k = 0

    reclaim = property(lambda self: self._parts.reclaim)
    scanning = property(lambda self: self._parts.scanning)
    instruments = property(lambda self: self._parts.instruments)
    neighbour = property(lambda self: self._parts.neighbour)
    faults = property(lambda self: self._parts.faults)

    @property
    def runs(self) -> int:
        return len(self.scenes)

    @property
    def nthread(self) -> int:
        return self._parts.nthread

    @property
    def time(self) -> np.ndarray:
        return self.tracking.time[: self.samples]

    @property
    def done(self) -> bool:
        return self.k >= self.samples

    @property
    def duration(self) -> float:
        """s from the first control period to the last (for a bench reclaim, the most it may take)."""
        return (self.samples - 1) * self.period

    @property
    def alive(self) -> np.ndarray | None:
        """Indices of the runs still stepped; None: all."""
        return self._plant.alive

    @functools.cached_property
    def q_true(self) -> np.ndarray:
        """(runs, 3) read-only: the true joint positions (m, rad). Like the views below, made once:
        drivers read them every period."""
        return read_only(self._plant.qpos)

    @functools.cached_property
    def qd_true(self) -> np.ndarray:
        """(runs, 3) read-only: the true joint velocities (m/s, rad/s)."""
        return read_only(self._plant.qvel)

    @functools.cached_property
    def drive_force(self) -> np.ndarray:
        """(runs, 3) read-only: the forces the drives applied in the last period (N, N m)."""
        return read_only(self._plant.drive_force)

    @property
    def wind_speed(self) -> np.ndarray | None:
        """(runs,) m/s: the wind along its heading in the last period, as an anemometer reads it
        (the mean before the first); None when every run is in still air."""
        return self._plant.wind_speed

    @functools.cached_property
    def failures(self) -> types.MappingProxyType:
        """Run index -> why it stopped."""
        return types.MappingProxyType(self._plant.failures)

    @functools.cached_property
    def path(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """A path scene's read-only (samples, 3) reference positions, velocities and accelerations,
        the same for every run; None for a bench reclaim."""
        return tuple(read_only(rows) for rows in self.tracking.rows) if self.tracking.shared else None

    @functools.cached_property
    def reclaim_rate(self) -> np.ndarray | None:
        """(runs,) t/h on the belt this period (read-only), or None without a stockpile."""
        return None if self.reclaim is None else read_only(self.reclaim.rate)

    def reference_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Period k's reference: position, velocity, acceleration, (3,) for every run or (runs, 3)
        (each run's own under an interlock, which decides it as the period is measured)."""
        return self.tracking.now()

    def controller_context(self) -> ControllerContext:
        """What a controller of these runs may know: the belief machine, never the plant."""
        return ControllerContext(self.runs, self.period, self.belief_machine, self.nthread)

    def record_controller(self, controller: Controller) -> None:
        """Record the signals `controller` declares (`Controller.signals`); before the first period."""
        signals = tuple(getattr(controller, "signals", ()))
        if self._observer is not None:
            self._observer.watch_controller(signals, self.samples)
            self._block = self._block.with_controller(signals)
        self._controller = controller

    def measure(self) -> tuple[np.ndarray, np.ndarray]:
        """The encoders' (runs, 3) positions and velocities at the start of period k (read-only); once a period."""
        k, block = self.k, self._block
        row = block.rows[block.row]
        for stage in self._hooks.measure:
            stage.measure(k, row)
        return row.q_measured_view, row.qd_measured_view

    def advance(self, command: np.ndarray) -> None:
        """Hold the (runs, 3) drive forces (N, N m) over period k, with the period's disturbances."""
        k, block, plant, tracking, hooks = self.k, self._block, self._plant, self.tracking, self._hooks
        row = block.rows[block.row]
        applied = row.command
        applied[...] = command
        if first_non_finite(applied) >= 0:
            self._stop_non_finite(applied)
        phase = tracking.phase()
        for watcher in self._parts.watchers:  # before the world acts on the period
            watcher.watch(k, row)
        for stage in hooks.world:
            stage.world(k, row)
        if hooks.drives:  # the drives apply the command, unless a stage overrides it
            applied = block.applied
            applied[...] = row.command
            for stage in hooks.drives:
                stage.drives(k, applied)
        plant.step(applied, row.disturbance, row.gust)
        plant.read(row.q_next, row.qd_next, row.drive_force)
        for stage in hooks.stepped:
            stage.stepped(k, row)
        controller = self._controller
        for name, rows in row.controller:
            rows[...] = getattr(controller, name)
        self.k = k = k + 1
        tracking.advance(k, phase)
        if tracking.samples != self.samples:
            self._resize(tracking.samples)
        block.row += 1
        if block.row == block.length:
            self._reduce()
        if k % HEALTH_CHECK_EVERY == 0:
            plant.check_health()
        if k == self.samples:
            for stage in hooks.finish:
                stage.finish(k)
            tracking.finish()
            self._reduce()
            plant.check_health()

    def _resize(self, samples: int) -> None:
        """The runs take `samples` periods, as the reference now has it: fewer once every run
        rests, more once a survey's benches are planned."""
        if self._observer is not None:
            (self._observer.extend_to if samples > self.samples else self._observer.end_at)(samples)
        self.samples = samples

    def _reduce(self) -> None:
        """The block's rows into the metrics and the record; on with a new block."""
        if self._observer is not None:
            self._observer.reduce(self._block)
        self._block.roll()

    def _stop_non_finite(self, command: np.ndarray) -> None:
        """Stop the runs whose drive forces are not finite: theirs, not the plant's, failure."""
        for run in np.flatnonzero(~np.isfinite(command).all(axis=1)):
            if run in self._plant.failures:
                continue
            axis = int(np.flatnonzero(~np.isfinite(command[run]))[0])
            self._stopped.add(int(run))
            self._plant.fail(int(run), f"{self.command_source} gave {command[run, axis]} for {AXES[axis]}")

    def results(self) -> list[RunResult | SimulationError]:
        """Each run's result, or the SimulationError of a run that diverged; once `done`."""
        if not self.done:
            raise RuntimeError(f"the lockstep is at control period {self.k} of {self.samples}")
        if self._observer is None:
            raise RuntimeError("this lockstep was built with observe=False: it keeps no results")
        return [self._failure(run) or self._result(run) for run in range(self.runs)]

    def _failure(self, run: int) -> SimulationError | None:
        path, failures = self.scenes[run].path, self._plant.failures
        if run in self._stopped:
            return SimulationError(f"{path}: {failures[run]}; the run stopped there")
        if run in failures:
            return SimulationError(f"{path}: the simulation diverged ({failures[run]}); try smaller gains or timestep")
        return None

    def _result(self, run: int) -> RunResult:
        """Run `run`'s result: the observer's metrics and record, with each watcher's and stage's share."""
        scene, stages, recorder = self.scenes[run], self._hooks, self._observer.recorder
        metrics = self._observer.metrics.result(run, self.time)
        for part in (*self._parts.watchers, *stages.metrics):  # the watchers' first: the interlock adds to theirs
            part.metrics(run, metrics)
        if "reclaim" in metrics:  # how the run carried out its plan
            metrics["reclaim"].update(self.tracking.reclaim_metrics(run))
        metrics["run"] = {
            "scene": str(scene.path),
            "mjcf": str(scene.machine.mjcf),
            "controller_mjcf": str(scene.controller_mjcf),
            "seed": scene.simulation.seed,
            "duration": self.duration,
            "control_period": self.period,
            "timestep": scene.simulation.timestep,
            **self.tracking.run_metrics(run),
        }
        waypoints, _ = self.tracking.waypoints(run)
        result = recorder.run_result(run, scene=scene, machine=self.machine, trajectory=waypoints,
                                     time=self.time, metrics=metrics)
        for stage in stages.result:
            stage.result(run, result, recorder)
        for section in SECTIONS:  # metrics.json's sections in the contract's order
            if section in metrics:
                metrics[section] = metrics.pop(section)
        return result


# metrics.json's sections after the loop's own (docs/contracts.md), in order
SECTIONS = ("reclaim", "scan", "stacking", "blend", "collision", "run", "faults")


@numba.njit(cache=True)
def first_non_finite(values: np.ndarray) -> int:  # pragma: no cover - compiled
    """The flat index of the first NaN or infinity in `values` (any layout), or -1: the check
    every driver's drive forces, and an agent's actions, pass before they reach the plant."""
    i = 0
    for value in values.flat:
        if not np.isfinite(value):
            return i
        i += 1
    return -1
