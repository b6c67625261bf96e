"""The encoders: what the controller knows of the machine's joints, for every run at once.

Positions are quantised to each run's encoder resolution. The velocity is either the plant's
true joint velocity (the paper's Simulink signal) or an estimate from the quantised positions:
a backward difference through a first-order low-pass of the scene's time constant.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.config.scene import EncoderSection


class Encoders:
    """Measures (runs, 3) joint states; holds the velocity estimate's filter state."""

    def __init__(self, settings: Sequence[EncoderSection], period: float, q0: np.ndarray):
        """`settings` one per run, `period` the control period in s, `q0` the (3,) or (runs, 3)
        joint values the runs start at (m, rad, rad)."""
        runs = len(settings)
        self._resolution = np.array([s.resolution for s in settings])
        self._estimate = np.array([s.velocity_source == "encoder" for s in settings])[:, None]
        self._any_estimate = bool(self._estimate.any())
        self._filter_gain = np.array([period / (s.velocity_filter + period) for s in settings])[:, None]
        self._period = period
        self._q_previous = self.quantise(np.broadcast_to(q0, (runs, 3)))
        self._qd_estimate = np.zeros((runs, 3))

    def quantise(self, q: np.ndarray) -> np.ndarray:
        """Positions rounded to the encoder resolution, (runs, 3)."""
        return np.round(q / self._resolution) * self._resolution

    def measure(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured positions and velocities from the true (runs, 3) joint state; call once a period."""
        q_measured = self.quantise(q)
        if not self._any_estimate:
            return q_measured, qd
        difference = (q_measured - self._q_previous) / self._period
        self._qd_estimate += (difference - self._qd_estimate) * self._filter_gain
        self._q_previous = q_measured
        return q_measured, np.where(self._estimate, self._qd_estimate, qd)
