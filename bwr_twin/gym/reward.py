"""The reward: the negative weighted square of the true tracking error, per control period.

    r = -(w_travel (e_travel / s_travel)^2 + w_slew (e_slew / s_slew)^2 + w_luff (e_luff / s_luff)^2)

e = q_ref - q at the end of the period (the plant's true joints, not the encoders'; past the
path's end the reference is its end point), s the observation's error scale (`Scales.error`:
0.1 m at the CP by default), w the weights (default 1, 1, 1). A run that stays 0.1 m off on
every axis earns -3 a period.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.gym.kernels import reward

DEFAULT_WEIGHTS = (1.0, 1.0, 1.0)


def tracking_reward(error: np.ndarray, scale: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(runs,) rewards of (runs, 3) true position errors (m, rad), summed axis by axis in a fixed
    order: a run's reward does not depend on its neighbours."""
    out = np.empty(len(error))
    reward(np.ascontiguousarray(error, dtype=float), scale, weights, out)
    return out
