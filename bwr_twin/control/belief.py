"""The controller's belief of the machine: its mass matrix and bias forces at the measured state.

The belief is the closed form of the believed machine's M(q) and bias(q, qd) (the scene's
`controller_mjcf`, or the plant's file compiled apart; `bwr_twin.model.dynamics`), identified
from its compiled model and checked against MuJoCo's: for every run of a lockstep, one compiled
pass at the *measured* joint state gives M(q̂) and bias(q̂, q̂̇) = Coriolis, centrifugal and
gravity forces. The bias holds no friction: joint damping and friction loss in the belief's file
never enter the control law, by design.
"""

from __future__ import annotations

import numba
import numpy as np

from bwr_twin.model.dynamics import evaluate
from bwr_twin.model.machine import Machine


class Belief:
    """M and bias of every run's machine, as the controller believes it to be.

    Attributes:
        machine: the believed machine (kinematics, drive limits).
        mass_matrix: (runs, 3, 3) M at the state of the last `update`, in kg, kg m and kg m^2;
            `bias` (runs, 3) the Coriolis, centrifugal and gravity forces there, in N and N m.
    """

    def __init__(self, machine: Machine, runs: int):
        self.machine = machine
        self._dynamics = machine.dynamics
        self.mass_matrix = np.zeros((runs, 3, 3))
        self.bias = np.zeros((runs, 3))
        self._every_run = np.arange(runs, dtype=np.int64)

    def update(self, q: np.ndarray, qd: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Compute M and bias at the (runs, 3) measured state, for the runs `ids` (None: all)."""
        dynamics = self._dynamics
        evaluate(dynamics.mass, dynamics.gravity, q, qd, self._ids(ids), self.mass_matrix, self.bias)

    def torque_at(self, q: np.ndarray, qd: np.ndarray, u: np.ndarray, ids: np.ndarray | None = None) -> np.ndarray:
        """`update(q, qd, ids)`, then `torque(u)`, in one compiled call."""
        out = np.empty(u.shape)
        dynamics = self._dynamics
        _torque_at(dynamics.mass, dynamics.gravity, q, qd, self._ids(ids), self.mass_matrix, self.bias, u, out)
        return out

    def _ids(self, ids: np.ndarray | None) -> np.ndarray:
        """The runs to compute, as the compiled pass takes them (None: all)."""
        return self._every_run if ids is None else np.asarray(ids, dtype=np.int64)

    def torque(self, u: np.ndarray) -> np.ndarray:
        """tau = M u + bias (runs, 3) at the state of the last `update`, for the accelerations u
        (runs, 3). M u is summed row by row in a fixed order: a run's force does not depend on its
        neighbours."""
        out = np.empty(u.shape)
        _torque(self.mass_matrix, u, self.bias, out)
        return out


@numba.njit(cache=True)
def _torque_at(mass_coefficients, gravity_coefficients, q, qd, ids, mass, bias, u, out):  # pragma: no cover
    evaluate(mass_coefficients, gravity_coefficients, q, qd, ids, mass, bias)
    _torque(mass, u, bias, out)


@numba.njit(cache=True)
def _torque(mass, u, bias, out):  # pragma: no cover - compiled
    runs, nv = u.shape
    for r in range(runs):
        for i in range(nv):
            inertial = 0.0
            for j in range(nv):
                inertial += mass[r, i, j] * u[r, j]
            out[r, i] = inertial + bias[r, i]
