"""The controller's belief of the machine: its mass matrix and bias forces at the measured state.

The belief is its own compiled model (the scene's `controller_mjcf`, or the plant's file
compiled apart), stepped never: for every run of a lockstep, one `Batch.forward` to the velocity
stage at the *measured* joint state gives M(q̂) and bias(q̂, q̂̇) = Coriolis, centrifugal and
gravity forces. `qfrc_bias` holds no friction: joint damping and friction loss in the belief's
file never enter the control law, by design.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
from mujoco.batch import Batch

from bwr_twin.model.machine import Machine


class Belief:
    """M and bias of every run's machine, as the controller believes it to be.

    Attributes:
        machine: the believed machine (kinematics, drive limits).
        bias: (runs, 3) Coriolis, centrifugal and gravity forces at the state of the last
            `update`, in N and N m; `mass_matrix` M there.
    """

    def __init__(self, machine: Machine, runs: int, *, nthread: int = 0):
        self.machine = machine
        model = machine.physics_model(rigid_body_only=True)
        self._batch = batch = Batch(model, runs, nthread=nthread)
        self._qpos = batch.bind("qpos")
        self._qvel = batch.bind("qvel")
        self._sparse_mass = batch.bind("M")  # MuJoCo's CSR lower triangle, bound before any call
        self.bias = batch.bind("qfrc_bias")
        # Where each entry of the dense, symmetric M sits in the sparse lower triangle.
        nv = model.nv
        self._dense_index = np.zeros((nv, nv), dtype=np.int64)
        for i in range(nv):
            for a in range(model.M_rowadr[i], model.M_rowadr[i] + model.M_rownnz[i]):
                j = model.M_colind[a]
                self._dense_index[i, j] = self._dense_index[j, i] = a
        self._dense_index = self._dense_index.ravel()
        self._mass_matrix = np.zeros((runs, nv, nv))
        self._dense_current = False

    def update(self, q: np.ndarray, qd: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Compute M and bias at the (runs, 3) measured state, for the runs `ids` (None: all)."""
        self._qpos[...] = q
        self._qvel[...] = qd
        # Positions give M (composite rigid bodies), velocities the bias (Newton-Euler, no qacc).
        self._batch.forward(ids, stage=mujoco.mjtStage.mjSTAGE_VEL)
        self._dense_current = False

    @property
    def mass_matrix(self) -> np.ndarray:
        """(runs, 3, 3) M at the state of the last `update`, in kg and kg m^2 (dense, made on demand)."""
        if not self._dense_current:
            np.take(self._sparse_mass, self._dense_index, axis=1, out=self._mass_matrix.reshape(len(self._mass_matrix), -1))
            self._dense_current = True
        return self._mass_matrix

    def torque(self, u: np.ndarray) -> np.ndarray:
        """tau = M u + bias (runs, 3) at the state of the last `update`, for the accelerations u
        (runs, 3). M u is summed row by row in a fixed order: a run's force does not depend on its
        neighbours."""
        out = np.empty(u.shape)
        _torque(self._sparse_mass, self._dense_index, u, self.bias, out)
        return out


@numba.njit(cache=True)
def _torque(sparse_mass, dense_index, u, bias, out):  # pragma: no cover - compiled
    runs, nv = u.shape
    for r in range(runs):
        for i in range(nv):
            inertial = 0.0
            for j in range(nv):
                inertial += sparse_mass[r, dense_index[i * nv + j]] * u[r, j]
            out[r, i] = inertial + bias[r, i]
