"""Computed-torque PD: the textbook model-based controller, with the same belief the paper's
fuzzy controller uses.

    tau = M(q_hat) (qdd_ref + Kp e + Kd de/dt) + bias(q_hat, qd_hat),   e = q_ref - q_hat

M and bias come from the controller's belief at the measured state. With a perfect belief each
axis's error obeys e'' + Kd e' + Kp e = 0: Kp = w^2 and Kd = 2 zeta w set a natural frequency w
(rad/s) and damping ratio zeta per axis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.control.interface import Controller, ControllerContext, check_non_negative
from bwr_twin.signals import ACCELERATION_COMMAND

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ComputedTorqueSettings:
    """[controller] keys of `type = "computed_torque"`; per axis travel, slew, luff."""

    kp: Vec3  # 1/s^2: acceleration per unit of position error
    kd: Vec3  # 1/s: acceleration per unit of velocity error

    def validate(self) -> None:
        check_non_negative(self, "kp", "kd")


class ComputedTorqueController(Controller):
    """tau = M(q_hat) (qdd_ref + Kp e + Kd e') + bias(q_hat, qd_hat) for every run."""

    Settings = ComputedTorqueSettings
    signals = (ACCELERATION_COMMAND,)

    def __init__(self, context: ControllerContext, settings: Sequence[ComputedTorqueSettings]):
        super().__init__(context, settings)
        self.belief = context.belief
        self._kp, self._kd = self.per_run("kp"), self.per_run("kd")
        self.acceleration_command = np.zeros((context.runs, 3))

    def compute(self, q, qd, q_ref, qd_ref, qdd_ref, ids):
        u = self.acceleration_command
        np.add(qdd_ref, self._kp * (q_ref - q) + self._kd * (qd_ref - qd), out=u)
        return self.belief.torque_at(q, qd, u, ids)
