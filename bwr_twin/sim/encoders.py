"""The encoders: what the controller knows of the machine's joints, for every run at once.

Positions are quantised to each run's encoder resolution. The velocity is either the plant's
true joint velocity (the paper's Simulink signal) or an estimate from the quantised positions:
a backward difference through a first-order low-pass of the scene's time constant.
"""

from __future__ import annotations

import numba
import numpy as np

from bwr_twin.sim.parameters import RunParameters


class Encoders:
    """Measures (runs, 3) joint states; holds the velocity estimate's filter state."""

    def __init__(self, parameters: RunParameters, period: float, q0: np.ndarray):
        """`period` the control period in s, `q0` the (3,) or (runs, 3) joint values the runs
        start at (m, rad, rad)."""
        self._resolution = parameters.encoder_resolution
        self._estimate = parameters.velocity_estimated.copy()
        self._filter_gain = period / (parameters.velocity_filter + period)
        self._period = period
        self._q_previous = self.quantise(np.broadcast_to(q0, (parameters.runs, 3)))
        self._qd_estimate = np.zeros((parameters.runs, 3))

    def quantise(self, q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Positions rounded to the encoder resolution, (runs, 3)."""
        out = np.empty(q.shape) if out is None else out
        _quantise(q, self._resolution, out)
        return out

    def measure(self, q: np.ndarray, qd: np.ndarray, q_measured: np.ndarray, qd_measured: np.ndarray) -> None:
        """Write the measured positions and velocities of the true (runs, 3) joint state into
        `q_measured` and `qd_measured`; call once a period."""
        _measure(q, qd, self._resolution, self._estimate, self._filter_gain, self._period, self._q_previous,
                 self._qd_estimate, q_measured, qd_measured)


@numba.njit(cache=True)
def _quantise(q, resolution, out):  # pragma: no cover - compiled
    """round(q / resolution) x resolution, halves to even as numpy rounds."""
    for r in range(q.shape[0]):
        for j in range(q.shape[1]):
            out[r, j] = np.rint(q[r, j] / resolution[r, j]) * resolution[r, j]


@numba.njit(cache=True)
def _measure(q, qd, resolution, estimate, filter_gain, period, q_previous, qd_estimate, q_measured,
             qd_measured):  # pragma: no cover - compiled
    """Quantised positions; the true velocity, or, for the runs that estimate it, the backward
    difference of the quantised positions through the low-pass."""
    _quantise(q, resolution, q_measured)
    for r in range(q.shape[0]):
        for j in range(3):
            if estimate[r]:
                difference = (q_measured[r, j] - q_previous[r, j]) / period
                qd_estimate[r, j] += (difference - qd_estimate[r, j]) * filter_gain[r]
                q_previous[r, j] = q_measured[r, j]
                qd_measured[r, j] = qd_estimate[r, j]
            else:
                qd_measured[r, j] = qd[r, j]
