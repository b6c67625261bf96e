"""The paper's controller (Fig. 5 and 11): fuzzy logic on top of a model-based part, for every
run of a lockstep at once.

    tau = M(q_hat) u + bias(q_hat, qd_hat),   u_i = K_out,i * FLC(K_e e_i, K_ec ed_i) [+ qdd_d,i]

with e = q_d - q_hat. M and bias come from the controller's belief (`Belief`), at the measured
state; nothing of the plant's true state enters. Gains, input scales and feed-forward are per
run; the rule base (the fuzzy surface) is shared by the lockstep.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from bwr_twin.control.fuzzy import FuzzySurface, surface_at
from bwr_twin.control.interface import Controller, ControllerContext, SettingsError
from bwr_twin.control.rulebase import load_rule_base
from bwr_twin.signals import ACCELERATION_COMMAND, FUZZY_OUTPUT

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class FuzzyModelSettings:
    """[controller] keys of `type = "fuzzy_model"` (paper Sec. 3 and 5)."""

    rule_base: Path  # the fuzzy rule base: a TOML file (bwr_twin.control.rulebase) or a MATLAB .fis
    input_scale_e: float  # K_e, 1/m and 1/rad
    input_scale_ec: float  # K_ec, s/m and s/rad
    output_gain: Vec3  # K_out per axis: m/s^2 and rad/s^2 per unit of the output universe
    acceleration_feedforward: bool = False  # add the reference acceleration to u (not in the paper)

    def validate(self) -> None:
        for key in ("input_scale_e", "input_scale_ec"):
            if not getattr(self, key) > 0:
                raise SettingsError(key, f"must be > 0, got {getattr(self, key)}")
        for axis, gain in zip(("travel", "slew", "luff"), self.output_gain):
            if not gain > 0:
                raise SettingsError(f"output_gain ({axis})", f"must be > 0, got {gain}")


class FuzzyModelController(Controller):
    """Drive forces from measured and desired joint states, all (runs, 3).

    After `compute`, `fuzzy_output` (FLC output, in the output universe) and
    `acceleration_command` (u, m/s^2 and rad/s^2) hold this period's values: the signals it
    declares for the record.
    """

    Settings = FuzzyModelSettings
    signals = (FUZZY_OUTPUT, ACCELERATION_COMMAND)

    def __init__(self, context: ControllerContext, settings: Sequence[FuzzyModelSettings],
                 surface: FuzzySurface | None = None):
        super().__init__(context, settings)
        self.belief = context.belief
        self._surface = surface or FuzzySurface.load(load_rule_base(settings[0].rule_base))
        self._scale_e = self.per_run("input_scale_e")
        self._scale_ec = self.per_run("input_scale_ec")
        self._output_gain = self.per_run("output_gain")
        self._feedforward = np.array([s.acceleration_feedforward for s in settings])
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
        """Drive forces (N, N m, N m), (runs, 3); the desired states (3,) for every run, or (runs, 3).

        `ids` names the runs whose forces matter (None: all); the others get no belief update.
        """
        _acceleration_command(q_measured, qd_measured, q_desired, qd_desired, qdd_desired, self._scale_e,
                              self._scale_ec, self._output_gain, self._feedforward, self._surface.kernel,
                              self.fuzzy_output, self.acceleration_command)
        return self.belief.torque_at(q_measured, qd_measured, self.acceleration_command, ids)


@numba.njit(cache=True)
def _acceleration_command(q_measured, qd_measured, q_desired, qd_desired, qdd_desired, scale_e, scale_ec,
                          output_gain, feedforward, kernel, fuzzy_output, u):  # pragma: no cover - compiled
    """u_i = K_out,i FLC(K_e e_i, K_ec ed_i) [+ qdd_d,i] for every run and axis; the reference
    is (3,) when shared by every run, or (runs, 3)."""
    q_desired, qd_desired = q_desired.reshape((-1, 3)), qd_desired.reshape((-1, 3))
    qdd_desired = qdd_desired.reshape((-1, 3))
    runs = q_measured.shape[0]
    shared = q_desired.shape[0] == 1
    for r in range(runs):
        rr = 0 if shared else r
        for j in range(3):
            je, jec = (0 if scale_e.shape[1] == 1 else j), (0 if scale_ec.shape[1] == 1 else j)
            e = (q_desired[rr, j] - q_measured[r, j]) * scale_e[r, je]
            ec = (qd_desired[rr, j] - qd_measured[r, j]) * scale_ec[r, jec]
            fuzzy_output[r, j] = surface_at(kernel, e, ec)
            u[r, j] = fuzzy_output[r, j] * output_gain[r, j]
            if feedforward[r]:
                u[r, j] += qdd_desired[rr, j]
