"""The closed loop for many runs at once: trajectory -> encoders -> controller -> plant, one
control period at a time, every signal a (runs, 3) array.

A lockstep is a group of runs of one machine, path, controller (and rule base) and timing; what may differ
between its runs (seeds, gains, input scales, encoders, disturbances, friction loss, wind) is
per-run data. `lockstep_key` says which runs may share a lockstep. A single run is a lockstep of
one: `simulate(scene)` is `simulate_lockstep([scene])[0]`, and a run's result does not depend
on which runs share its lockstep.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.control.interface import ControllerContext, shared_settings
from bwr_twin.control.registry import controller_class
from bwr_twin.errors import BwrError, EnvelopeError, SimulationError, UnreachableError
from bwr_twin.model.machine import Machine
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.results.metrics import OnlineMetrics
from bwr_twin.results.record import Recorder, RunResult
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.plant import Plant, mujoco_warnings

HEALTH_CHECK_EVERY = 100  # control periods between checks for divergence, and progress reports

Progress = Callable[[float, float], None]


def lockstep_key(scene: Scene) -> tuple:
    """What the runs of one lockstep share: the compiled models, the path, the controller and
    its settings other than numbers (a rule base, say), the timing."""
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
    )


def simulate(scene: Scene, *, progress: Progress | None = None, nthread: int = 0) -> RunResult:
    """Run one scene headless. Raises BwrError subclasses on bad input or divergence.

    `progress(done, total)`, if given, hears how many of the path's seconds are simulated, about
    once a simulated second.
    """
    (result,) = simulate_lockstep([scene], progress=progress, nthread=nthread)
    if isinstance(result, BwrError):
        raise result
    return result


def simulate_lockstep(
    scenes: Sequence[Scene], *, progress: Progress | None = None, nthread: int = 0
) -> list[RunResult | SimulationError]:
    """Run scenes that share a `lockstep_key` together, on `nthread` threads (0: all cores; never
    more threads than runs).

    Returns one RunResult per scene, in order, or the SimulationError of a run that diverged
    (the others go on). Raises BwrError if the path or a model is bad: that fails every run.
    """
    if len({lockstep_key(s) for s in scenes}) != 1:
        raise ValueError("the scenes of a lockstep must share their lockstep_key")
    scene = scenes[0]
    machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload)
    belief_machine = Machine(scene.controller_mjcf)  # its own compiled model, even from the same file
    try:
        trajectory = Trajectory.plan(scene.trajectory, machine)
    except (UnreachableError, EnvelopeError) as exc:
        raise type(exc)(f"{scene.path}: {exc}") from None
    runs = len(scenes)
    nthread = min(nthread or os.cpu_count() or 1, runs)
    period = scene.simulation.control_period
    samples = round(trajectory.duration / period) + 1
    time = trajectory.times[0] + np.arange(samples) * period
    q_desired, qd_desired, qdd_desired = trajectory.sample(time)
    cp_desired = machine.fk(q_desired)

    plant = Plant(machine, scenes, q0=trajectory.knots[0], nthread=nthread)
    encoders = Encoders([s.encoders for s in scenes], period, trajectory.knots[0])
    context = ControllerContext(runs, period, belief_machine, nthread)
    controller = controller_class(scene.controller.type)(context, [s.controller.settings for s in scenes])
    unrecorded = np.full((runs, 3), np.nan)  # what a controller does not compute
    disturbances = Disturbances(scenes, period)
    recorder = Recorder(samples, round(scene.simulation.record_period / period), runs)
    metrics = OnlineMetrics(runs, machine.drive_limits, machine.envelope, machine.joint_range, period)

    wind_mean = np.array([s.plant.wind_speed for s in scenes])
    errors_and_forces = np.zeros((runs, 12))
    columns = {name: errors_and_forces[:, getattr(OnlineMetrics, name)]
               for name in ("POSITION", "VELOCITY", "ACCELERATION", "FORCE")}
    qdd, qd_mean = np.zeros((runs, 3)), np.zeros((runs, 3))

    def finish(j: int, q: np.ndarray, qd: np.ndarray, qd_next: np.ndarray, inputs: tuple) -> None:
        """Sample j's metrics and record, once its period has ended at velocity qd_next. Runs
        before the next period's control: the controller and plant still hold sample j's."""
        np.subtract(q_desired[j], q, out=columns["POSITION"])
        np.subtract(qd_desired[j], qd, out=columns["VELOCITY"])
        np.divide(np.subtract(qd_next, qd, out=qdd), period, out=qdd)  # mean over the period
        np.subtract(qdd_desired[j], qdd, out=columns["ACCELERATION"])
        np.copyto(columns["FORCE"], plant.drive_force)
        q_measured, qd_measured, command, disturbance, gust = inputs
        np.multiply(np.add(qd, qd_next, out=qd_mean), 0.5, out=qd_mean)
        metrics.add(j, errors_and_forces, command, q, qd_mean)
        row = recorder.row(j)
        if row < 0:
            return
        metrics.add_cp_error(j, np.linalg.norm(cp_desired[j] - machine.fk(q), axis=1))
        for name, value in (("q_desired", q_desired[j]), ("q", q), ("q_measured", q_measured),
                            ("qd_desired", qd_desired[j]), ("qd", qd), ("qd_measured", qd_measured),
                            ("qdd_desired", qdd_desired[j]), ("qdd", qdd),
                            ("fuzzy_output", _or(controller.fuzzy_output, unrecorded)),
                            ("acceleration_command", _or(controller.acceleration_command, unrecorded)),
                            ("drive_force_command", command), ("drive_force", plant.drive_force),
                            ("disturbance", disturbance)):
            recorder.signals[name][row] = value
        recorder.wind_speed[row] = wind_mean + gust

    q, qd, q_last, qd_last = (np.zeros((runs, 3)) for _ in range(4))
    inputs: tuple = ()
    with mujoco_warnings():
        for k in range(samples):
            q, q_last, qd, qd_last = q_last, q, qd_last, qd  # this period's buffers; last period's kept
            np.copyto(q, plant.qpos)
            np.copyto(qd, plant.qvel)
            if k:
                finish(k - 1, q_last, qd_last, qd, inputs)
            q_measured, qd_measured = encoders.measure(q, qd)
            command = controller.compute(q_measured, qd_measured, q_desired[k], qd_desired[k],
                                         qdd_desired[k], plant.alive)
            disturbance = disturbances.forces.sample(k)
            gust = disturbances.gusts.sample(k)
            plant.step(command, disturbance, gust)
            inputs = (q_measured, qd_measured, command, disturbance, gust)
            if k % HEALTH_CHECK_EVERY == HEALTH_CHECK_EVERY - 1:
                plant.check_health()
                if progress is not None:
                    progress((k + 1) * period, trajectory.duration)
        finish(samples - 1, q, qd, plant.qvel, inputs)
        plant.check_health()

    results: list[RunResult | SimulationError] = []
    for run, run_scene in enumerate(scenes):
        if run in plant.failures:
            results.append(SimulationError(
                f"{run_scene.path}: the simulation diverged ({plant.failures[run]}); try smaller gains or timestep"
            ))
            continue
        run_metrics = metrics.result(run, time)
        run_metrics["run"] = {
            "scene": str(run_scene.path),
            "mjcf": str(run_scene.machine.mjcf),
            "controller_mjcf": str(run_scene.controller_mjcf),
            "seed": run_scene.simulation.seed,
            "duration": trajectory.duration,
            "control_period": period,
            "timestep": run_scene.simulation.timestep,
        }
        results.append(recorder.run_result(run, scene=run_scene, machine=machine, trajectory=trajectory,
                                           time=time, metrics=run_metrics))
    return results


def _or(signal: np.ndarray | None, missing: np.ndarray) -> np.ndarray:
    return missing if signal is None else signal
