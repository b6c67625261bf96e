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
read-only views. Each period's raw signals go into the observer's rows
(`bwr_twin.sim.observer`), which reduces them into metrics and records a block at a time.
"""

from __future__ import annotations

import os
import types
from collections.abc import Callable, Sequence

import numba
import numpy as np

from bwr_twin.collision.guard import Guard
from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import WATCH, PileClearance
from bwr_twin.config.faults import check_fault_scanners
from bwr_twin.config.plugin_calls import call, checked, construct, describe
from bwr_twin.config.plugins import controller_class
from bwr_twin.config.scene import Scene
from bwr_twin.control.interface import Controller, ControllerContext, shared_settings
from bwr_twin.errors import BwrError, SceneError, SimulationError
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.pile.surface import build_surface
from bwr_twin.sensing.faults import Faults
from bwr_twin.sensing.rate_instruments import rate_instruments, rate_loop_reads_instruments
from bwr_twin.sensing.scanning import Scanning, active_scanners, pile_model
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.fault_report import fault_metrics
from bwr_twin.sim.neighbour import Neighbour
from bwr_twin.sim.observer import Observer
from bwr_twin.sim.parameters import RunParameters
from bwr_twin.sim.plant import Plant, mujoco_warnings
from bwr_twin.sim.record import ReclaimRecord, RunResult
from bwr_twin.sim.tracking import BenchTracking, PathTracking, StackingTracking
from bwr_twin.stockpile.reclaim import Reclaim
from bwr_twin.stockpile.stacking import Stacking

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
    """The runs of one lockstep, advanced a control period at a time by whoever computes the
    drive forces.

    Each period k: `measure()` gives the encoders' reading, `reference_now()` the reference
    and `advance(command)` holds the drive forces for the period. After the last period
    (`done`), `results()` gives each run's result.

    Attributes:
        machine: the plant's machine; `belief_machine` the controller's.
        tracking: what the runs follow (bwr_twin.sim.tracking): a path shared by every run, or a
            bench plan each run follows on its own.
        time: the (samples,) times of the control periods (s); `samples` their count (for a
            bench reclaim, the most it may take until it ends).
        k: the control period about to be measured and advanced.
        q_true, qd_true, drive_force: read-only (runs, 3) views of the true joint state and of the
            forces the drives applied in the last period; `failures` maps a run that stopped to why.
        path: a path scene's read-only (samples, 3) reference rows, or None.
        reclaim: the piles being dug and their accounting, or None if the scene has no stockpile.
        scanning: the runs' scanners and the piles they know from them (bwr_twin.sensing), or
            None without a stockpile or a scanner.
        instruments: the runs' belt scale and wheel current (bwr_twin.sensing.rate_instruments),
            read every period and recorded, or None without a stockpile or instruments; a bench
            reclaim's rate control reads them unless [sensing] rate_signals is "exact".
        collision: the machine's collision shapes against the runs' piles
            (bwr_twin.collision.monitor), or None without a pile or shapes.
        neighbour: a second machine on the rail and its schedule (bwr_twin.sim.neighbour), or
            None; `machines` the two machines' shapes against each other
            (bwr_twin.collision.machines), or None.
        interlock: the anti-collision interlock and the reference it paces
            (bwr_twin.collision.guard), or None.
        faults: the scene's scheduled faults (bwr_twin.sensing.faults); `faults.acting(k)` says
            which act in period k.
    """

    def __init__(self, scenes: Sequence[Scene], *, nthread: int = 0, pile_frame_period: float | None = None,
                 observe: bool = True):
        """Raises BwrError if the path, a model or the stockpile is bad. `pile_frame_period` (s):
        keep the pile as it is dug that often, for a replay. `observe=False`: no metrics and no
        record (a driver that keeps its own, such as a learning agent's environment)."""
        if len({lockstep_key(s) for s in scenes}) != 1:
            raise ValueError("the scenes of a lockstep must share their lockstep_key")
        self.scenes = list(scenes)
        scene = scenes[0]
        sim = scene.simulation
        parameters = RunParameters.of(scenes)
        surface = build_surface(scene.stockpile, scene.path) if scene.stockpile is not None else None
        self.machine = machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload, stockpile=surface,
                                         stockpile_drawing=scene.stockpile)
        self.belief_machine = Machine(scene.controller_mjcf)  # its own compiled model, even from the same file
        self.runs = runs = len(scenes)
        self.nthread = min(nthread or os.cpu_count() or 1, runs)
        self.period = period = sim.control_period
        scanners = active_scanners(scene, machine) if surface is not None else ()
        self.instruments = rate_instruments(scene, machine, parameters.seed, period)
        if scene.reclaim is not None:
            scanned = pile_model(scene, scanners) == "scanned"
            measured = rate_loop_reads_instruments(scene, machine)
            tracking = BenchTracking(scenes, machine, period, instruments=self.instruments if measured else None,
                                     known_pile=(lambda: self.scanning.survey.z[0]) if scanned else None)
        elif scene.stacking is not None:
            tracking = StackingTracking(scene, machine, period)
        else:
            tracking = PathTracking(scene, machine, period)
        self.tracking = tracking
        self.samples, self.time = tracking.samples, tracking.time
        frame_every = max(round(pile_frame_period / period), 1) if pile_frame_period else None
        self.stacking = (Stacking(scenes, machine, tracking.pattern, period, (tracking.samples - 1) * period,
                                  frame_every) if scene.stacking is not None else None)

        self.neighbour = Neighbour(scenes, period) if scene.neighbour is not None else None
        self._plant = plant = Plant(machine, parameters, q0=tracking.start, timestep=sim.timestep,
                                    control_period=period, nthread=self.nthread, neighbour=self.neighbour)
        self._encoders = Encoders(parameters, period, tracking.start)
        self.faults = faults = Faults(scene.faults, parameters.seed, period)
        self._applied = np.zeros((runs, 3))  # the drive forces applied, where a quick stop or a trip overrides the command
        self._disturbances = Disturbances(parameters, period)
        self.reclaim = None
        if surface is not None:
            self.reclaim = Reclaim(scenes, machine, surface, period, frame_every)
        check_fault_scanners(scene.path, scene.faults, [s.name for s in scanners], scene.machine.mjcf)
        self.collision = (PileClearance(machine.collision_shapes, surface, runs, period)
                          if surface is not None and machine.collision_shapes else None)
        self.machines = None
        if self.neighbour is not None:
            bare = [m.path.name for m in (machine, self.neighbour.machine) if not m.collision_shapes]
            if bare:
                raise SceneError(f"{scene.path}: [neighbour]: the machines' clearance needs both to have collision "
                                 f"shapes, but {' and '.join(bare)} has none (geoms 'collision_<part>' in group 5, "
                                 "docs/anticollision.md)")
            self.machines = MachineClearance(machine, self.neighbour.machine, runs, period)
        self.interlock = None
        if scene.interlock is not None:
            if not machine.collision_shapes:
                raise SceneError(f"{scene.path}: [interlock] keeps the machine's collision shapes clear of the pile, "
                                 f"but {machine.path.name} has none (geoms 'collision_<part>' in group 5, "
                                 "docs/anticollision.md)")
            self.interlock = Guard(scene, machine, surface, runs, period, tracking.rows if tracking.shared else None,
                                   neighbour=self.neighbour.machine if self.neighbour is not None else None)
        nan = np.full(runs, np.nan)  # the readings of a machine without instruments
        self._instrument_readings = ((self.instruments.belt_scale, self.instruments.wheel_current)
                                     if self.instruments is not None else (nan, nan))
        self.scanning = (Scanning(scanners, surface, parameters.seed, period, self.reclaim.density,
                                  keep_scans=observe, faults=faults) if scanners else None)
        self._observe = observe
        self._observer = observer = Observer(
            runs, self.samples, period, round(sim.record_period / period), machine,
            path=tracking.rows if tracking.shared and self.interlock is None else None, wind_mean=parameters.wind_speed,
            reclaim=self.reclaim is not None, neighbour=self.neighbour is not None)
        observer.q[0], observer.qd[0] = plant.qpos, plant.qvel  # the first period's start
        if not observe:  # one row, whose end state is the next period's start
            row = observer.rows[0]
            row.q_next, row.qd_next = row.q, row.qd
        self._controller: Controller | None = None  # whose declared signals are recorded
        self.command_source = "the drive forces given"  # who computes them, for messages
        self._stopped: set[int] = set()  # runs stopped for non-finite drive forces
        # What drivers may read: views that cannot be written.
        self.q_true, self.qd_true, self.drive_force = (_read_only(a) for a in (plant.qpos, plant.qvel,
                                                                               plant.drive_force))
        self.failures = types.MappingProxyType(plant.failures)  # run index -> why it stopped
        # A path scene's (samples, 3) reference positions, velocities and accelerations, the same
        # for every run; None for a bench reclaim.
        self.path = tuple(_read_only(rows) for rows in tracking.rows) if tracking.shared else None
        self._measured = (_read_only(observer.q_measured), _read_only(observer.qd_measured))
        self.k = 0

    def _collision_metrics(self, run: int) -> dict:
        """metrics.json's `collision` object of `run`: the shapes against the pile and the neighbour."""
        collision = (self.collision.metrics(run) if self.collision is not None
                     else {"watch_m": WATCH, "pile": {}, "contacts": [], "interventions": [],
                           "periods": self.k, "measured_periods": 0})
        if self.interlock is not None:
            collision["interventions"] = self.interlock.interventions(run)
        if self.machines is not None:
            pairs, contacts = self.machines.metrics(run)
            collision["machines"] = pairs
            collision["contacts"] = sorted(collision["contacts"] + contacts, key=lambda e: e["time_s"])
            collision["machine_measured_periods"] = int(self.machines.measured_periods[run])
        return collision

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

    @property
    def reclaim_rate(self) -> np.ndarray | None:
        """(runs,) t/h on the belt this period (read-only), or None without a stockpile."""
        return None if self.reclaim is None else _read_only(self.reclaim.rate)

    def reference_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Period k's reference: position, velocity, acceleration, (3,) for every run or (runs, 3)
        (each run's own under an interlock, which decides it as the period is measured)."""
        if self.interlock is not None and self.tracking.shared:
            lock = self.interlock
            return lock.q, lock.qd, lock.qdd
        return self.tracking.now()

    def controller_context(self) -> ControllerContext:
        """What a controller of these runs may know: the belief machine, never the plant."""
        return ControllerContext(self.runs, self.period, self.belief_machine, self.nthread)

    def record_controller(self, controller: Controller) -> None:
        """Record the signals `controller` declares (`Controller.signals`); before the first period."""
        signals = tuple(getattr(controller, "signals", ()))
        self._observer.watch_controller(signals, self.samples)
        self._controller = controller

    def measure(self) -> tuple[np.ndarray, np.ndarray]:
        """The encoders' (runs, 3) positions and velocities at the start of period k (read-only); once a period."""
        observer = self._observer
        row = observer.rows[observer.row]
        self._encoders.measure(row.q, row.qd, row.q_measured, row.qd_measured)
        if self.faults.active:  # the controller sees what the faulty encoders show
            self.faults.measured(self.k, row.q_measured, row.qd_measured)
        neighbour = self.neighbour
        if neighbour is not None:  # what the automation hears of the neighbour
            neighbour.hear(self.k, self._plant.neighbour_q, self._plant.neighbour_qd)
        if self.interlock is not None:  # ... and so does the interlock, which decides this period's reference
            known = (self.scanning.survey.z if self.scanning is not None
                     else self.reclaim.cutter.heights if self.reclaim is not None else None)
            self.interlock.decide(self.k, row.q_measured, row.qd_measured, row.qd, known,
                                  neighbour.reported if neighbour is not None else None)
            if not self.tracking.shared:  # a bench plan's follower takes it from the next period on
                self.tracking.pace = self.interlock.pace
            if neighbour is not None:  # the same pace holds the neighbour's schedule
                neighbour.pace = self.interlock.pace
        q_measured, qd_measured = self._measured
        return q_measured[observer.row], qd_measured[observer.row]

    def advance(self, command: np.ndarray) -> None:
        """Hold the (runs, 3) drive forces (N, N m) over period k, with the period's disturbances."""
        k, observer, plant, tracking = self.k, self._observer, self._plant, self.tracking
        row = observer.rows[observer.row]
        row.command[...] = command
        if first_non_finite(row.command) >= 0:
            self._stop_non_finite(row.command)
        disturbance = row.disturbance
        disturbance[...] = self._disturbances.forces.sample(k)
        phase = tracking.phase()
        reclaim = self.reclaim
        if self.scanning is not None:  # the pile as dug until this period, seen from where the machine stands
            self._scan(k, row.q)
        if self.collision is not None:  # ... and the machine's clearance to it
            self.collision.step(k, row.q, row.qd, reclaim.cutter.heights, plant.alive)
        if self.machines is not None:  # ... and to its neighbour
            self.machines.step(k, row.q, row.qd, plant.neighbour_q, plant.neighbour_qd, plant.alive)
        if self.stacking is not None:  # the stream lands where the discharge point stands
            self.stacking.step(k, row.q, plant.alive)
        if reclaim is not None:
            load = reclaim.step(k, row.q, plant.alive)
            if load is not None:
                disturbance += load
            instruments = self.instruments
            if instruments is not None:
                instruments.read(k, reclaim.rate, reclaim.power, self.faults.active and self.faults.scale_frozen(k))
            for rows, value in zip(row.reclaim, (reclaim.rate, reclaim.depth, reclaim.power, reclaim.force,
                                                 *self._instrument_readings)):
                rows[...] = value
        gusts = self._disturbances.gusts
        if gusts.active:  # still air leaves the row's zeros
            row.gust[...] = gusts.sample(k)
        applied = row.command
        quick_stop = self.interlock.interlock.quick_stop if self.interlock is not None else None
        stopping = quick_stop is not None and quick_stop.any()
        if self.faults.active or stopping:
            applied = self._applied
            applied[...] = row.command
            if stopping:  # the interlock's quick stop: the drives brake on their own, whatever commanded
                plant.quick_stop(quick_stop, applied)
            if self.faults.active:  # a tripped drive applies nothing, whatever it was commanded
                self.faults.command(k, applied)
        if row.neighbour is not None:  # where the neighbour stands as the period starts
            row.neighbour[1][...] = plant.neighbour_q
        plant.step(applied, disturbance, row.gust)
        plant.read(row.q_next, row.qd_next, row.drive_force)
        if row.neighbour is not None:  # ... and the schedule it held this period
            row.neighbour[0][...] = self.neighbour.q_reference
        if row.reference is not None:  # a per-run reference changes in place: the record keeps this period's
            for rows, value in zip(row.reference, self.reference_now()):
                rows[...] = value
        if self.interlock is not None:
            self.interlock.advance()
        controller = self._controller
        for name, rows in row.controller:
            rows[...] = getattr(controller, name)
        self.k = k = k + 1
        end = tracking.advance(k, reclaim, phase)
        if end is not None and end < self.samples:
            self.samples = end
            self.time = self.time[:end]
            observer.end_at(end)
        if k == tracking.survey_end:  # the survey has ended: the benches are planned from here
            if tracking.samples > self.samples:  # on the pile the runs scanned, just now
                self.samples, self.time = tracking.samples, tracking.time
                observer.extend_to(self.samples)
            if self.scanning is not None:
                self.scanning.note_plan_start(k * self.period, reclaim.cutter.heights)
        if self._observe:
            observer.period_done()
        if k % HEALTH_CHECK_EVERY == 0:
            plant.check_health()
        if k == self.samples:
            if reclaim is not None:
                reclaim.finish(k - 1)
                tracking.finish(reclaim)
            if self._observe:
                observer.flush()
            plant.check_health()

    def _scan(self, k: int, q: np.ndarray) -> None:
        """Period k's scans, and the scanned piles of the runs whose wheel has just begun to cut."""
        scanning, heights = self.scanning, self.reclaim.cutter.heights
        if scanning.step(k, q, heights, self._plant.alive) and scanning.awaiting_first_cut:
            scanning.note_first_cut(k * self.period, self.reclaim.conveyor.dug > 0, heights)

    def _stop_non_finite(self, command: np.ndarray) -> None:
        """Stop the runs whose drive forces are not finite: theirs, not the plant's, failure."""
        for run in np.flatnonzero(~np.isfinite(command).all(axis=1)):
            if run in self.failures:
                continue
            axis = int(np.flatnonzero(~np.isfinite(command[run]))[0])
            self._stopped.add(int(run))
            self._plant.fail(int(run), f"{self.command_source} gave {command[run, axis]} for {AXES[axis]}")

    def results(self) -> list[RunResult | SimulationError]:
        """Each run's result, or the SimulationError of a run that diverged; once `done`."""
        if not self.done:
            raise RuntimeError(f"the lockstep is at control period {self.k} of {self.samples}")
        if not self._observe:
            raise RuntimeError("this lockstep was built with observe=False: it keeps no results")
        recorder, metrics = self._observer.recorder, self._observer.metrics
        results: list[RunResult | SimulationError] = []
        for run, scene in enumerate(self.scenes):
            if run in self._stopped:
                results.append(SimulationError(f"{scene.path}: {self.failures[run]}; the run stopped there"))
                continue
            if run in self.failures:
                results.append(SimulationError(
                    f"{scene.path}: the simulation diverged ({self.failures[run]}); try smaller gains or timestep"
                ))
                continue
            run_metrics = metrics.result(run, self.time)
            if self.reclaim is not None:
                run_metrics["reclaim"] = {**self.reclaim.metrics(run),
                                          **self.tracking.reclaim_metrics(run, float(self.reclaim.density[run]))}
            if self.scanning is not None:
                run_metrics["scan"] = self.scanning.metrics(run, self.reclaim.cutter.heights[run])
            if self.stacking is not None:
                run_metrics["stacking"] = self.stacking.metrics(run)
            if self.reclaim is not None and self.reclaim.stacked is not None:
                run_metrics["blend"] = self.reclaim.blend_metrics(run)
            if self.collision is not None or self.machines is not None:
                run_metrics["collision"] = self._collision_metrics(run)
            run_metrics["run"] = {
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
                                         time=self.time, metrics=run_metrics)
            if self.reclaim is not None:
                result.reclaim = ReclaimRecord(**recorder.reclaim_share(run), **self.reclaim.pile(run),
                                               grade_out=self.reclaim.grade_out(run))
            if self.scanning is not None:
                result.scan = self.scanning.record(run, self.duration)
            if self.stacking is not None:
                result.stacking = self.stacking.record(run)
            if scene.faults:
                run_metrics["faults"] = fault_metrics(
                    scene.faults, result.time, result.q_desired, result.q, run_metrics,
                    result.reclaim.rate if result.reclaim is not None else None,
                    scene.reclaim.target_rate if scene.reclaim is not None else None)
            results.append(result)
        return results


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


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view
