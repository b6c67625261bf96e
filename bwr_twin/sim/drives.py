"""The drives' own loops, which act without the controller: a neighbour's drives holding its
schedule (bwr_twin.sim.neighbour) and a quick stop (bwr_twin.collision.interlock).

Both are the loops a drive converter closes on its motor's own speed feedback: each axis a
mass-spring-damper on the inertia it has at a pose given (the diagonal of the mass matrix), its
bias forces (gravity) compensated with MuJoCo's, within the drives' force limits.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np

from bwr_twin.model.machine import Machine


def inertia_at(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(3,) the diagonal of the machine's mass matrix at q: each drive's inertia there."""
    model = machine.model
    data = mujoco.MjData(model)
    data.qpos[machine.joint_ids] = q
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dofs = model.jnt_dofadr[machine.joint_ids]
    return full[dofs, dofs].copy()


@numba.njit(cache=True)
def hold(reference, q, qd, bias, inertia, w, limits, out):  # pragma: no cover - compiled
    """(runs, 3) forces into `out`: bias + inertia x (the reference's acceleration + w^2 x the
    position error + 2 w x the velocity error), within the drives' (3, 2) limits; `reference`
    (runs, 3, 3) each run's position, velocity and acceleration."""
    for r in range(q.shape[0]):
        for j in range(3):
            force = bias[r, j] + inertia[j] * (reference[r, 2, j] + w * w * (reference[r, 0, j] - q[r, j])
                                               + 2.0 * w * (reference[r, 1, j] - qd[r, j]))
            out[r, j] = min(max(force, limits[j, 0]), limits[j, 1])


@numba.njit(cache=True)
def quick_stop(stopped, qd, bias, inertia, period, limits, out):  # pragma: no cover - compiled
    """The forces of the runs `stopped` (runs,) into their rows of `out` (runs, 3): each drive
    brakes its speed qd to zero within one control `period`, as far as its limits allow, then holds
    it there (a drive's quick stop, on its own speed feedback: not the encoders')."""
    for r in range(qd.shape[0]):
        if stopped[r]:
            for j in range(3):
                force = bias[r, j] - inertia[j] * qd[r, j] / period
                out[r, j] = min(max(force, limits[j, 0]), limits[j, 1])
