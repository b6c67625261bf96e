"""A per-axis PID, as a drive PLC runs it: the baseline every reclaimer engineer knows.

    tau_i = clip(F0_i + Kp_i e_i + Ki_i integral(e_i) + Kd_i de_i/dt, drive limits of axis i)

with e = q_ref - q_measured and de/dt = qd_ref - qd_measured. No model of the machine enters:
the drives' loads are left to the integral, after a constant holding force F0 (the static load
found at commissioning, as the torque a luff drive proves before its brake opens; without it
the boom sags until the integral has caught up). The output is clipped to the
drive ratings of the believed machine's MJCF (none on the paper's machine). Anti-windup by
conditional integration: while an axis is saturated, its integral stops growing in the direction
that drives it further into saturation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.control.interface import Controller, ControllerContext, check_non_negative

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class PidSettings:
    """[controller] keys of `type = "pid"`; per axis travel, slew, luff."""

    kp: Vec3  # N/m, N m/rad, N m/rad
    ki: Vec3  # N/(m s), N m/(rad s), N m/(rad s)
    kd: Vec3  # N s/m, N m s/rad, N m s/rad
    holding_force: Vec3 = (0.0, 0.0, 0.0)  # F0: N, N m, N m, added to the output

    def validate(self) -> None:
        check_non_negative(self, "kp", "ki", "kd")


class PidController(Controller):
    """Per-axis PID with output limits from the drive ratings and conditional integration."""

    Settings = PidSettings

    def __init__(self, context: ControllerContext, settings: Sequence[PidSettings]):
        super().__init__(context, settings)
        self._kp, self._ki, self._kd = (self.per_run(k) for k in ("kp", "ki", "kd"))
        self._holding = self.per_run("holding_force")
        self._low, self._high = context.machine.drive_limits[:, 0], context.machine.drive_limits[:, 1]
        self._dt = context.control_period
        self._integral = np.zeros((context.runs, 3))  # m s, rad s

    def compute(self, q, qd, q_ref, qd_ref, qdd_ref, ids):
        force = np.empty(q.shape)
        _pid(q, qd, q_ref.reshape(-1, 3), qd_ref.reshape(-1, 3), self._kp, self._ki, self._kd, self._holding,
             self._low, self._high, self._dt, self._integral, force)
        return force


@numba.njit(cache=True)
def _pid(q, qd, q_ref, qd_ref, kp, ki, kd, holding, low, high, dt, integral, force):  # pragma: no cover - compiled
    """The law for every run and axis; the reference is (1, 3) when shared by every run. The
    integral grows unless the output is saturated with the error pushing further the same way."""
    shared = q_ref.shape[0] == 1
    for r in range(q.shape[0]):
        rr = 0 if shared else r
        for j in range(3):
            e = q_ref[rr, j] - q[r, j]
            unclipped = holding[r, j] + kp[r, j] * e + ki[r, j] * integral[r, j] + kd[r, j] * (qd_ref[rr, j] - qd[r, j])
            force[r, j] = min(max(unclipped, low[j]), high[j])
            winding = (unclipped > high[j] and e > 0) or (unclipped < low[j] and e < 0)
            integral[r, j] += 0.0 if winding else e * dt
