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
        ctrl = batch.bind("ctrl")
        self._drives = _Drives(machine, ctrl, batch.bind("qfrc_applied"))
        # A quick stop brakes on each drive's inertia at the start pose, within its limits.
        self._quick_stop = _QuickStop(self.qvel, batch.bind("qfrc_bias")[:, :3],
                                      inertia_at(machine, np.broadcast_to(q0, (runs, 3))[0]),
                                      machine.drive_limits, control_period)
        self.neighbour = neighbour
        self._rail = None if neighbour is None else _NeighbourDrive(
            neighbour, qpos[:, 3:6], qvel[:, 3:6], batch.bind("qfrc_bias")[:, 3:6], model, ctrl)
        substeps = round(control_period / timestep)
        # A control period in calls of at most STEPS_PER_CALL: Ctrl-C is heard between calls.
        whole, rest = divmod(substeps, STEPS_PER_CALL)
        self._calls = [STEPS_PER_CALL] * whole + ([rest] if rest else [])

        given = ~np.isnan(parameters.frictionloss).any(axis=1)
        if given.any():
            batch.expand("dof_frictionloss")[given] = parameters.frictionloss[given]
        self._wind = _Wind(batch, parameters) if parameters.windy.any() else None

        self._warning_counts = batch.warning[:, :, 1]  # (runs, warning kinds), live
        self.qpos[:] = q0
        batch.forward()
        self.failures: dict[int, str] = {}
        self.alive: np.ndarray | None = None  # indices of the runs still stepped; None: all

    @property
    def neighbour_q(self) -> np.ndarray:
        """Live (runs, 3) view of the neighbour's joints; AttributeError without a neighbour."""
        return self._neighbour_rail().q

    @property
    def neighbour_qd(self) -> np.ndarray:
        """Live (runs, 3) view of the neighbour's joint speeds; AttributeError without a neighbour."""
        return self._neighbour_rail().qd

    @property
    def wind_speed(self) -> np.ndarray | None:
        """(runs,) m/s: each run's wind along its heading in the last period (its mean before the
        first); None when every run is in still air."""
        return None if self._wind is None else self._wind.speed

    def _neighbour_rail(self) -> _NeighbourDrive:
        if self._rail is None:
            raise AttributeError("this plant has no neighbour on its rail")
        return self._rail

    def step(self, drive_force: np.ndarray, disturbance: np.ndarray, gust: np.ndarray) -> None:
        """Hold the (runs, 3) drive forces and disturbances, and each run's (runs,) gust on its
        mean wind, for one control period."""
        drives = self._drives
        _hold(drive_force, drives.gear, drives.actuators, disturbance, drives.ctrl, drives.applied)
        if self._rail is not None:
            self._rail.drive()
        if self._wind is not None:
            self._wind.blow(gust)
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
        self._quick_stop.apply(stopped, drive_force)

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


class _Drives:
    """The machine's drives as MuJoCo sees them: live views of the controls and of the applied
    forces, and each drive's actuator column and gear (a force is held as force over gear)."""

    def __init__(self, machine: Machine, ctrl: np.ndarray, applied: np.ndarray):
        ids = list(machine.actuator_ids)
        self.ctrl, self.applied = ctrl, applied
        self.actuators = np.array(ids, dtype=np.int64)  # the drives' columns of ctrl, in joint order
        self.gear = machine.model.actuator_gear[ids, 0].copy()


class _QuickStop:
    """A quick stop: each drive brakes its own speed on its inertia at the start pose, within its
    force limits, in one control period (bwr_twin.sim.drives); only an interlock asks for it,
    and it reads the batch's live speeds and bias forces."""

    def __init__(self, qvel: np.ndarray, bias: np.ndarray, inertia: np.ndarray, limits: np.ndarray,
                 period: float):
        self._qvel, self._bias, self._inertia, self._limits, self._period = qvel, bias, inertia, limits, period

    def apply(self, stopped: np.ndarray, drive_force: np.ndarray) -> None:
        quick_stop(stopped, self._qvel, self._bias, self._inertia, self._period, self._limits, drive_force)


class _NeighbourDrive:
    """A second machine on the rail: live views of its joints (the model's fourth to sixth) and
    the controls through which its `neighbour` (bwr_twin.sim.neighbour) works its drives."""

    def __init__(self, neighbour: Neighbour, q: np.ndarray, qd: np.ndarray, bias: np.ndarray,
                 model: mujoco.MjModel, ctrl: np.ndarray):
        self.neighbour, self.q, self.qd, self._bias, self.ctrl = neighbour, q, qd, bias, ctrl
        own = neighbour.machine
        # Its actuators follow the machine's in the combined model.
        self._actuators = np.array(own.actuator_ids, dtype=np.int64) + model.nu - own.model.nu
        self._gear = own.model.actuator_gear[list(own.actuator_ids), 0].copy()
        self.q[:] = neighbour.start

    def drive(self) -> None:
        """The neighbour's drive forces for this period, from where it stands and how it moves."""
        force = self.neighbour.forces(self.q, self.qd, self._bias)
        _drive(force, self._gear, self._actuators, self.ctrl)


class _Wind:
    """Each run's wind: a mean speed from its heading, plus the period's gust, written into the
    per-simulation `opt.wind`; still runs get zero air density, so still air costs no drag."""

    def __init__(self, batch: Batch, parameters: RunParameters):
        batch.expand("opt.density")[:] = np.where(parameters.windy, parameters.air_density, 0.0)
        self._wind = batch.expand("opt.wind")
        heading = parameters.wind_direction
        self._direction = np.stack([np.cos(heading), np.sin(heading), np.zeros(parameters.runs)], axis=1)
        self._mean = parameters.wind_speed
        self.speed = self._mean.copy()  # (runs,) m/s along each heading in the last period: what an anemometer reads

    def blow(self, gust: np.ndarray) -> None:
        """Set each run's wind for the period: its mean plus its (runs,) gust, along its heading."""
        np.add(self._mean, gust, out=self.speed)
        self._wind[:] = self.speed[:, None] * self._direction


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


class mujoco_warnings:
    """Collect MuJoCo's warning texts instead of letting MuJoCo print them and write a log file.

    A class rather than a generator: a Gymnasium step enters it every control period."""

    __slots__ = ("_previous", "texts")

    def __enter__(self) -> list[str]:
        self._previous = mujoco.get_mju_user_warning()
        self.texts: list[str] = []
        mujoco.set_mju_user_warning(self.texts.append)
        return self.texts

    def __exit__(self, *exc_info) -> None:
        mujoco.set_mju_user_warning(self._previous)
