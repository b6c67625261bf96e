"""The plant: the machine as it really is, and the only owner of the simulated state.

MuJoCo steps it with the joint damping and friction of its MJCF (or the scene's), the drive
forces go through its actuators (which honour their force limits), random disturbance forces
enter through `qfrc_applied`, and wind acts through MuJoCo's fluid model. The controller sees it
only through its encoders: quantised positions and a velocity that is either the true one or an
estimate from those quantised positions.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import mujoco
import numpy as np

from bwr_twin.errors import SimulationError
from bwr_twin.machine import Machine
from bwr_twin.scene import Scene


class Plant:
    """Steps the machine one control period at a time under zero-order-hold drive forces."""

    def __init__(self, machine: Machine, scene: Scene, q0: np.ndarray):
        self.machine = machine
        self.model = model = machine.model
        sim, plant = scene.simulation, scene.plant
        model.opt.timestep = sim.timestep
        if plant.frictionloss is not None:
            model.dof_frictionloss[:] = plant.frictionloss
        model.opt.density = plant.air_density if (plant.wind_speed or plant.gust_amplitude) else 0.0
        heading = np.radians(plant.wind_direction)
        self._wind_direction = np.array([np.cos(heading), np.sin(heading), 0.0])
        self._wind_speed = plant.wind_speed
        self.set_wind_gust(0.0)

        self.data = mujoco.MjData(model)
        self.data.qpos[:] = q0
        mujoco.mj_forward(model, self.data)
        self._substeps = round(sim.control_period / sim.timestep)
        self._gear = model.actuator_gear[machine.actuator_ids, 0].copy()
        self._actuator_ids = np.array(machine.actuator_ids)

        # Encoders.
        self._resolution = np.array(scene.encoders.resolution)
        self._estimate_velocity = scene.controller.velocity_source == "encoder"
        self._filter_gain = sim.control_period / (scene.controller.velocity_filter + sim.control_period)
        self._period = sim.control_period
        self.q_measured = np.zeros(3)
        self.qd_measured = np.zeros(3)
        self._q_previous = np.zeros(3)
        self._difference = np.zeros(3)
        self._quantise(self.data.qpos, self._q_previous)

    def set_wind_gust(self, gust: float) -> None:
        """Wind speed = mean + gust (m/s), along the scene's wind direction."""
        self.model.opt.wind[:] = (self._wind_speed + gust) * self._wind_direction

    def _quantise(self, q: np.ndarray, out: np.ndarray) -> None:
        np.divide(q, self._resolution, out=out)
        np.round(out, out=out)
        out *= self._resolution

    def measure(self) -> None:
        """Update `q_measured` and `qd_measured` from the encoders."""
        self._quantise(self.data.qpos, self.q_measured)
        if self._estimate_velocity:
            # Backward difference of the quantised positions through a first-order low-pass.
            np.subtract(self.q_measured, self._q_previous, out=self._difference)
            self._difference /= self._period
            self._difference -= self.qd_measured
            self._difference *= self._filter_gain
            self.qd_measured += self._difference
            self._q_previous[:] = self.q_measured
        else:
            self.qd_measured[:] = self.data.qvel

    def step(self, drive_force: np.ndarray, disturbance: np.ndarray) -> None:
        """Hold the drive forces (N, N m) and the disturbance for one control period."""
        data = self.data
        data.ctrl[self._actuator_ids] = drive_force / self._gear
        data.qfrc_applied[:] = disturbance
        mujoco.mj_step(self.model, data, self._substeps)

    def check_health(self, warnings: list[str]) -> None:
        """Raise SimulationError if MuJoCo warned (it resets a diverged state) or the state is not finite.

        `warnings` holds the texts MuJoCo reported (see `mujoco_warnings`).
        """
        data = self.data
        for i, warning in enumerate(data.warning):
            if warning.number:
                text = warnings[0].strip() if warnings else mujoco.mjtWarning(i).name
                raise SimulationError(f"the simulation diverged (MuJoCo: {text}); try smaller gains or timestep")
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            raise SimulationError(f"the simulation diverged near t = {data.time:.2f} s: non-finite state")


@contextlib.contextmanager
def mujoco_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warning texts instead of letting MuJoCo print them to stderr."""
    previous = mujoco.get_mju_user_warning()
    texts: list[str] = []
    mujoco.set_mju_user_warning(texts.append)
    try:
        yield texts
    finally:
        mujoco.set_mju_user_warning(previous)
