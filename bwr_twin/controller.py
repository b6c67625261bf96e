"""The paper's controller (Fig. 5 and 11): fuzzy logic on top of a model-based part.

    tau = M(q_hat) u + bias(q_hat, qd_hat),   u_i = K_out,i * FLC(K_e e_i, K_ec ed_i) [+ qdd_d,i]

with e = q_d - q_hat. The model-based part owns its own MjModel/MjData, the controller's belief
of the machine, which it sets to the measured state (never the plant's true state). Friction is
absent from that belief: `qfrc_bias` holds Coriolis, centrifugal and gravity forces only, and
joint damping or friction loss in the belief's file never enter the control law.
"""

from __future__ import annotations

import mujoco
import numpy as np

from bwr_twin.fuzzy import FuzzySurface
from bwr_twin.machine import Machine
from bwr_twin.scene import ControllerSection


class FuzzyModelController:
    """Computes drive forces from measured and desired joint states; allocation-free per call.

    After `compute`, the attributes `fuzzy_output` (FLC output, in the output universe),
    `acceleration_command` (u, m/s^2 and rad/s^2) and `force` (tau, N and N m) hold this
    period's values.
    """

    def __init__(self, belief: Machine, settings: ControllerSection, surface: FuzzySurface):
        self.belief = belief
        self._model = belief.model
        self._data = mujoco.MjData(self._model)
        self._surface = surface
        self._input_scale_e = settings.input_scale_e
        self._input_scale_ec = settings.input_scale_ec
        self._output_gain = np.array(settings.output_gain)
        self._feedforward = settings.acceleration_feedforward
        self._mass_matrix = np.zeros((3, 3))
        self._e = np.zeros(3)
        self._ec = np.zeros(3)
        self.fuzzy_output = np.zeros(3)
        self.acceleration_command = np.zeros(3)
        self.force = np.zeros(3)

    def compute(
        self,
        q_measured: np.ndarray,
        qd_measured: np.ndarray,
        q_desired: np.ndarray,
        qd_desired: np.ndarray,
        qdd_desired: np.ndarray,
    ) -> np.ndarray:
        """Drive forces (N, N m, N m) for this control period; returns `self.force`."""
        np.subtract(q_desired, q_measured, out=self._e)
        self._e *= self._input_scale_e
        np.subtract(qd_desired, qd_measured, out=self._ec)
        self._ec *= self._input_scale_ec
        self._surface.evaluate(self._e, self._ec, out=self.fuzzy_output)
        np.multiply(self.fuzzy_output, self._output_gain, out=self.acceleration_command)
        if self._feedforward:
            self.acceleration_command += qdd_desired

        model, data = self._model, self._data
        data.qpos[:] = q_measured
        data.qvel[:] = qd_measured
        # The minimal pipeline for M and bias: positions -> composite inertia (qM) -> velocities
        # -> recursive Newton-Euler without acceleration (Coriolis, centrifugal, gravity). No
        # passive forces, no constraints: the belief holds no friction by design.
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_crb(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_rne(model, data, 0, data.qfrc_bias)
        mujoco.mj_fullM(model, data, self._mass_matrix)
        np.matmul(self._mass_matrix, self.acceleration_command, out=self.force)
        self.force += data.qfrc_bias
        return self.force
