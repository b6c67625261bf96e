"""The paper's controller (Fig. 5 and 11): fuzzy logic on top of a model-based part, for every
run of a lockstep at once.

    tau = M(q_hat) u + bias(q_hat, qd_hat),   u_i = K_out,i * FLC(K_e e_i, K_ec ed_i) [+ qdd_d,i]

with e = q_d - q_hat. M and bias come from the controller's belief (`Belief`), at the measured
state; nothing of the plant's true state enters. Gains, input scales and feed-forward are per
run; the rule base (the fuzzy surface) is shared by the lockstep.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.config.scene import ControllerSection
from bwr_twin.control.belief import Belief
from bwr_twin.control.fuzzy import FuzzySurface


class FuzzyModelController:
    """Drive forces from measured and desired joint states, all (runs, 3).

    After `compute`, `fuzzy_output` (FLC output, in the output universe) and
    `acceleration_command` (u, m/s^2 and rad/s^2) hold this period's values.
    """

    def __init__(self, belief: Belief, settings: Sequence[ControllerSection], surface: FuzzySurface):
        self.belief = belief
        self._surface = surface
        self._scale_e = np.array([s.input_scale_e for s in settings])[:, None]
        self._scale_ec = np.array([s.input_scale_ec for s in settings])[:, None]
        self._output_gain = np.array([s.output_gain for s in settings])
        self._feedforward = np.array([s.acceleration_feedforward for s in settings])[:, None]
        self._any_feedforward = bool(self._feedforward.any())
        self._e = np.zeros(self._output_gain.shape)
        self._ec = np.zeros(self._output_gain.shape)
        self.fuzzy_output = np.zeros(self._output_gain.shape)
        self.acceleration_command = np.zeros(self._output_gain.shape)

    def compute(
        self,
        q_measured: np.ndarray,
        qd_measured: np.ndarray,
        q_desired: np.ndarray,
        qd_desired: np.ndarray,
        qdd_desired: np.ndarray,
        ids: np.ndarray | None = None,
    ) -> np.ndarray:
        """Drive forces (N, N m, N m), (runs, 3); the desired states broadcast against (runs, 3).

        `ids` names the runs whose forces matter (None: all); the others get no belief update.
        """
        e, ec, u = self._e, self._ec, self.acceleration_command
        np.subtract(q_desired, q_measured, out=e)
        e *= self._scale_e
        np.subtract(qd_desired, qd_measured, out=ec)
        ec *= self._scale_ec
        # Flat views: a lockstep of one takes the surface's scalar fast path, with the same result.
        self._surface.evaluate(e.ravel(), ec.ravel(), out=self.fuzzy_output.ravel())
        np.multiply(self.fuzzy_output, self._output_gain, out=u)
        if self._any_feedforward:
            np.add(u, qdd_desired, out=u, where=self._feedforward)
        self.belief.update(q_measured, qd_measured, ids)
        # M u row by row, summed in a fixed order: a run's force does not depend on its neighbours.
        inertial = (self.belief.mass_matrix * u[:, None, :]).sum(axis=2)
        return inertial + self.belief.bias
