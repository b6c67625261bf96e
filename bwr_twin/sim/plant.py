"""The plant: the machines as they really are, one per run (with a neighbour on its rail where
the scene has one), and the only owner of their state.

All runs of a lockstep step together through one `mujoco.batch.Batch` of a physics-only copy of
the machine, on threads that release the GIL. Per-run values go into per-simulation model
fields (`Batch.expand`), never into the shared model: friction loss (`dof_frictionloss`), wind
(`opt.wind`) and air density (`opt.density`, zero for a run without wind, so that still air
costs no drag). The drive forces go through the actuators, which honour their force limits;
disturbance forces enter through `qfrc_applied`.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
from mujoco.batch import Batch
from mujoco.batch import SimulationError as BatchError

from bwr_twin.model.machine import Machine
from bwr_twin.sim.drives import inertia_at, quick_stop
from bwr_twin.sim.neighbour import Neighbour
from bwr_twin.sim.parameters import RunParameters

STEPS_PER_CALL = 1000  # physics steps of one Batch.step call: under a second even for 128 runs

# What MuJoCo's warnings mean, for messages (mjtWarning order).
_WARNINGS = {
    mujoco.mjtWarning.mjWARN_INERTIA: "a body's inertia is too small",
    mujoco.mjtWarning.mjWARN_CONTACTFULL: "too many contacts",
    mujoco.mjtWarning.mjWARN_CNSTRFULL: "too many constraints",
    mujoco.mjtWarning.mjWARN_BADQPOS: "bad joint positions",
    mujoco.mjtWarning.mjWARN_BADQVEL: "bad joint velocities",
    mujoco.mjtWarning.mjWARN_BADQACC: "bad joint accelerations",
    mujoco.mjtWarning.mjWARN_BADCTRL: "bad controls",
}


class Plant:
    """Steps every run's machine one control period at a time under zero-order-hold forces.

    Attributes:
        qpos, qvel: live (runs, 3) views of the true joint state (m, rad; m/s, rad/s).
        neighbour_q, neighbour_qd: the same of a second machine on the rail, whose drives its
            `neighbour` (bwr_twin.sim.neighbour) works each period; absent without one.
        drive_force: (runs, 3) forces the actuators applied in the last period (N, N m).
        failures: run index -> why it stopped (MuJoCo's error or warning, or a non-finite state);
            a failed run is no longer stepped, the others go on.
    """

    def __init__(self, machine: Machine, parameters: RunParameters, q0: np.ndarray, *, timestep: float,
                 control_period: float, nthread: int = 0, neighbour: Neighbour | None = None):
        runs = parameters.runs
        model = machine.physics_model(timestep, neighbour=neighbour.machine.path if neighbour else None)
        self.batch = batch = Batch(model, runs, nthread=nthread)
        qpos, qvel, actuator_force = batch.bind("qpos"), batch.bind("qvel"), batch.bind("qfrc_actuator")
        # The machine's joints are the model's first three; a neighbour's the next three.
        self.qpos, self.qvel, self.drive_force = qpos[:, :3], qvel[:, :3], actuator_force[:, :3]
        self._ctrl = batch.bind("ctrl")
        self._applied = batch.bind("qfrc_applied")
        ids = list(machine.actuator_ids)
        self._actuators = np.array(ids, dtype=np.int64)  # the drives' columns of ctrl, in joint order
        self._gear = machine.model.actuator_gear[ids, 0].copy()
        self._bias = batch.bind("qfrc_bias")[:, :3]
        # A quick stop brakes on each drive's inertia at the start pose, within its limits.
        self._inertia, self._limits = inertia_at(machine, np.broadcast_to(q0, (runs, 3))[0]), machine.drive_limits
        self._period = control_period
        self.neighbour = neighbour
        if neighbour is not None:
            self.neighbour_q, self.neighbour_qd = qpos[:, 3:6], qvel[:, 3:6]
            self._neighbour_bias = batch.bind("qfrc_bias")[:, 3:6]
            own = neighbour.machine
            self._neighbour_actuators = np.array(own.actuator_ids, dtype=np.int64) + model.nu - own.model.nu
            self._neighbour_gear = own.model.actuator_gear[list(own.actuator_ids), 0].copy()
            self.neighbour_q[:] = neighbour.start
        substeps = round(control_period / timestep)
        # A control period in calls of at most STEPS_PER_CALL: Ctrl-C is heard between calls.
        whole, rest = divmod(substeps, STEPS_PER_CALL)
        self._calls = [STEPS_PER_CALL] * whole + ([rest] if rest else [])

        given = ~np.isnan(parameters.frictionloss).any(axis=1)
        if given.any():
            batch.expand("dof_frictionloss")[given] = parameters.frictionloss[given]
        windy = parameters.windy
        self._wind = None
        if windy.any():
            batch.expand("opt.density")[:] = np.where(windy, parameters.air_density, 0.0)
            self._wind = batch.expand("opt.wind")
            heading = parameters.wind_direction
            self._wind_direction = np.stack([np.cos(heading), np.sin(heading), np.zeros(runs)], axis=1)
            self._wind_mean = parameters.wind_speed

        self._warning_counts = batch.warning[:, :, 1]  # (runs, warning kinds), live
        self.qpos[:] = q0
        batch.forward()
        self.failures: dict[int, str] = {}
        self.alive: np.ndarray | None = None  # indices of the runs still stepped; None: all

    def step(self, drive_force: np.ndarray, disturbance: np.ndarray, gust: np.ndarray) -> None:
        """Hold the (runs, 3) drive forces and disturbances, and each run's (runs,) gust on its
        mean wind, for one control period."""
        _hold(drive_force, self._gear, self._actuators, disturbance, self._ctrl, self._applied)
        if self.neighbour is not None:
            force = self.neighbour.forces(self.neighbour_q, self.neighbour_qd, self._neighbour_bias)
            _drive(force, self._neighbour_gear, self._neighbour_actuators, self._ctrl)
        if self._wind is not None:
            self._wind[:] = (self._wind_mean + gust)[:, None] * self._wind_direction
        for steps in self._calls:
            try:
                self.batch.step(self.alive, nstep=steps)
            except BatchError as exc:
                for run in exc.ids:
                    self.fail(int(run), f"MuJoCo: {self.batch.error(int(run))}")
        if _any(self._warning_counts):  # cheap each period, so a failure's time is exact
            self.check_health()

    def quick_stop(self, stopped: np.ndarray, drive_force: np.ndarray) -> None:
        """Replace the (runs, 3) drive forces of the runs `stopped` (runs,) with their drives' quick
        stop: each brakes its own speed to zero within a control period as far as its force limit
        allows, and holds it there (bwr_twin.sim.drives)."""
        quick_stop(stopped, self.qvel, self._bias, self._inertia, self._period, self._limits, drive_force)

    def read(self, q: np.ndarray, qd: np.ndarray, drive_force: np.ndarray) -> None:
        """Copy the (runs, 3) joint state and the drive forces of the last period into the arrays given."""
        _read(self.qpos, self.qvel, self.drive_force, q, qd, drive_force)

    def check_health(self) -> None:
        """Fail the runs that MuJoCo warned about (it resets a diverged state) or whose state is
        not finite."""
        warned = self._warning_counts > 0
        finite = np.isfinite(self.qpos).all(axis=1) & np.isfinite(self.qvel).all(axis=1)
        for run in np.flatnonzero(warned.any(axis=1) | ~finite):
            if run in self.failures:
                continue
            kinds = [_WARNINGS.get(mujoco.mjtWarning(w), mujoco.mjtWarning(w).name) for w in np.flatnonzero(warned[run])]
            self.fail(int(run), f"MuJoCo: {', '.join(kinds)}" if kinds else "non-finite state")

    def fail(self, run: int, reason: str) -> None:
        """Stop stepping `run`, for `reason` (the time is added); the others go on."""
        self.failures[run] = f"{reason}, near t = {self.batch.time[run]:.2f} s"
        self.alive = np.array([r for r in range(self.batch.nsim) if r not in self.failures], dtype=np.int64)


@numba.njit(cache=True)
def _hold(drive_force, gear, actuators, disturbance, ctrl, applied):  # pragma: no cover - compiled
    """The drives' controls (force over gear) and the disturbances, for every run."""
    for r in range(drive_force.shape[0]):
        for j in range(3):
            ctrl[r, actuators[j]] = drive_force[r, j] / gear[j]
            applied[r, j] = disturbance[r, j]


@numba.njit(cache=True)
def _drive(force, gear, actuators, ctrl):  # pragma: no cover - compiled
    """A neighbour's drives' controls (force over gear), for every run."""
    for r in range(force.shape[0]):
        for j in range(3):
            ctrl[r, actuators[j]] = force[r, j] / gear[j]


@numba.njit(cache=True)
def _read(qpos, qvel, actuator_force, q, qd, drive_force):  # pragma: no cover - compiled
    for r in range(qpos.shape[0]):
        for j in range(3):
            q[r, j], qd[r, j], drive_force[r, j] = qpos[r, j], qvel[r, j], actuator_force[r, j]


@numba.njit(cache=True)
def _any(counts):  # pragma: no cover - compiled
    for value in counts.flat:
        if value:
            return True
    return False


class mujoco_warnings:  # noqa: N801 - used as a function: `with mujoco_warnings() as texts:`
    """Collect MuJoCo's warning texts instead of letting MuJoCo print them and write a log file.

    A class rather than a generator: a Gymnasium step enters it every control period."""

    __slots__ = ("texts", "_previous")

    def __enter__(self) -> list[str]:
        self._previous = mujoco.get_mju_user_warning()
        self.texts: list[str] = []
        mujoco.set_mju_user_warning(self.texts.append)
        return self.texts

    def __exit__(self, *exc_info) -> None:
        mujoco.set_mju_user_warning(self._previous)
