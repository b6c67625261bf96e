"""The observation and action spaces of one environment."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from bwr_twin.gym.scales import OBSERVATION_LIMIT, OBSERVATION_SIZE


def observation_space() -> spaces.Box:
    """19 float32 entries in [-OBSERVATION_LIMIT, OBSERVATION_LIMIT] (layout: bwr_twin.gym.scales)."""
    return spaces.Box(-OBSERVATION_LIMIT, OBSERVATION_LIMIT, (OBSERVATION_SIZE,), dtype=np.float32)


def action_space() -> spaces.Box:
    """Travel, slew, luff in [-1, 1] (meaning: bwr_twin.gym.actions)."""
    return spaces.Box(-1.0, 1.0, (3,), dtype=np.float32)


def episode_seed(rng: np.random.Generator, seed: int | None) -> int:
    """The scene seed of an episode: `seed` if given, else the next draw of the environment's generator."""
    return int(seed) if seed is not None else int(rng.integers(2**31))
