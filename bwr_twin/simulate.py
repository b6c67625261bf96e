"""The closed loop: trajectory -> controller -> plant, one control period at a time.

`simulate` plans the path, builds the controller's belief and the plant from their own MJCF
files, runs the loop and returns every signal at the control rate. The loop allocates nothing:
signals go into preallocated arrays, disturbances are drawn up front from the scene's seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bwr_twin.controller import FuzzyModelController
from bwr_twin.errors import BwrError, EnvelopeError, SimulationError, UnreachableError
from bwr_twin.fuzzy import FuzzySurface
from bwr_twin.machine import Machine
from bwr_twin.plant import Plant, mujoco_warnings
from bwr_twin.rulebase import RuleBase
from bwr_twin.scene import Scene
from bwr_twin.trajectory import Trajectory

HEALTH_CHECK_EVERY = 100  # control periods between checks for MuJoCo warnings


@dataclass
class RunResult:
    """Every signal of one run, sampled at the control period. Arrays are (n,) or (n, 3),
    per axis in the order travel, slew, luff, in SI units (m, rad, s, N, N m)."""

    scene: Scene
    machine: Machine  # the plant's
    trajectory: Trajectory
    time: np.ndarray
    q_desired: np.ndarray
    qd_desired: np.ndarray
    qdd_desired: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray  # mean acceleration over the period that starts at each sample
    q_measured: np.ndarray
    qd_measured: np.ndarray
    fuzzy_output: np.ndarray  # FLC output, dimensionless (the output universe)
    acceleration_command: np.ndarray  # u
    drive_force_command: np.ndarray  # tau from the controller
    drive_force: np.ndarray  # what the actuators applied (after their force limits)
    disturbance: np.ndarray
    wind_speed: np.ndarray  # (n,), m/s along the wind direction

    @property
    def cp_desired(self) -> np.ndarray:
        return self.machine.fk(self.q_desired)

    @property
    def cp(self) -> np.ndarray:
        return self.machine.fk(self.q)


def held_random(rng: np.random.Generator, amplitude, n_samples: int, period: float, hold: float) -> np.ndarray:
    """Uniform noise in [-amplitude, amplitude], drawn once per `hold` seconds, sampled every `period`."""
    amplitude = np.asarray(amplitude, dtype=float)
    hold_index = np.floor(np.arange(n_samples) * period / hold + 1e-9).astype(int)
    draws = rng.uniform(-1.0, 1.0, size=(hold_index[-1] + 1,) + amplitude.shape)
    return draws[hold_index] * amplitude


def simulate(scene: Scene, *, progress: Callable[[float, float], None] | None = None) -> RunResult:
    """Run the scene's reclaim headless. Raises BwrError subclasses on bad input or divergence.

    `progress(done, total)`, if given, hears how many of the path's seconds are simulated, about
    once a simulated second.
    """
    machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload)
    belief = Machine(scene.controller_mjcf)  # its own compiled model, even from the same file
    try:
        trajectory = Trajectory.plan(scene.trajectory, machine)
    except (UnreachableError, EnvelopeError) as exc:
        raise _in_scene(scene, exc) from None
    surface = FuzzySurface.load(RuleBase.from_toml(scene.controller.rule_base))
    controller = FuzzyModelController(belief, scene.controller, surface)
    plant = Plant(machine, scene, q0=trajectory.knots[0])

    period = scene.simulation.control_period
    n = round(trajectory.duration / period) + 1
    time = trajectory.times[0] + np.arange(n) * period
    q_desired, qd_desired, qdd_desired = trajectory.sample(time)
    # Independent streams, so that turning gusts on leaves the disturbance sequence unchanged.
    disturbance_rng, gust_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(scene.simulation.seed).spawn(2))
    disturbance = held_random(disturbance_rng, scene.disturbance.amplitude, n, period, scene.disturbance.hold_time)
    gust = held_random(gust_rng, scene.plant.gust_amplitude, n, period, scene.plant.gust_hold_time)
    wind_speed = scene.plant.wind_speed + gust

    q, qd, q_measured, qd_measured, fuzzy, command, force_command, force = (np.zeros((n, 3)) for _ in range(8))
    data = plant.data
    plant.set_wind_gust(gust[0])
    with mujoco_warnings() as warnings:
        try:
            for k in range(n):
                q[k] = data.qpos
                qd[k] = data.qvel
                plant.measure()
                q_measured[k] = plant.q_measured
                qd_measured[k] = plant.qd_measured
                force_command[k] = controller.compute(
                    plant.q_measured, plant.qd_measured, q_desired[k], qd_desired[k], qdd_desired[k]
                )
                fuzzy[k] = controller.fuzzy_output
                command[k] = controller.acceleration_command
                if k and gust[k] != gust[k - 1]:
                    plant.set_wind_gust(gust[k])
                plant.step(controller.force, disturbance[k])
                force[k] = data.qfrc_actuator
                if k % HEALTH_CHECK_EVERY == HEALTH_CHECK_EVERY - 1:
                    plant.check_health(warnings)
                    if progress is not None:
                        progress((k + 1) * period, trajectory.duration)
            plant.check_health(warnings)
        except SimulationError as exc:
            raise _in_scene(scene, exc) from None
    qdd = np.empty_like(qd)
    qdd[:-1] = np.diff(qd, axis=0) / period
    qdd[-1] = (data.qvel - qd[-1]) / period
    return RunResult(
        scene=scene,
        machine=machine,
        trajectory=trajectory,
        time=time,
        q_desired=q_desired,
        qd_desired=qd_desired,
        qdd_desired=qdd_desired,
        q=q,
        qd=qd,
        qdd=qdd,
        q_measured=q_measured,
        qd_measured=qd_measured,
        fuzzy_output=fuzzy,
        acceleration_command=command,
        drive_force_command=force_command,
        drive_force=force,
        disturbance=disturbance,
        wind_speed=wind_speed,
    )


def _in_scene(scene: Scene, exc: BwrError) -> BwrError:
    """The same error, naming the scene file it came from."""
    return type(exc)(f"{scene.path}: {exc}")

