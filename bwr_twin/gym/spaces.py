"""The observation and action spaces of one environment, and the scene seed of an episode."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from bwr_twin.gym.scales import OBSERVATION_LIMIT, OBSERVATION_SIZE

ENV_ID = "bwr_twin/Reclaim-v0"
SCENE_SEEDS = 2**63  # the twin keeps a run's seed as an int64: scene seeds lie in [0, 2**63)


def observation_space(size: int = OBSERVATION_SIZE) -> spaces.Box:
    """`size` float32 entries in [-OBSERVATION_LIMIT, OBSERVATION_LIMIT]: 19, or 21 with the
    instruments (layout: bwr_twin.gym.scales)."""
    return spaces.Box(-OBSERVATION_LIMIT, OBSERVATION_LIMIT, (size,), dtype=np.float32)


def action_space() -> spaces.Box:
    """Travel, slew, luff in [-1, 1] (meaning: bwr_twin.gym.actions)."""
    return spaces.Box(-1.0, 1.0, (3,), dtype=np.float32)


def episode_seed(rng: np.random.Generator, seed: int | None) -> int:
    """The scene seed of an episode: `seed` if given (`scene_seed`), else the next draw of the
    environment's generator."""
    return scene_seed(int(seed)) if seed is not None else int(rng.integers(2**31))


def scene_seed(seed: int) -> int:
    """The scene seed of a Gymnasium seed (any int >= 0): the seed itself below 2**63, else 63
    bits of numpy's SeedSequence of it, so that every seed Gymnasium takes gives its own runs."""
    if seed < SCENE_SEEDS:
        return seed
    return int(np.random.SeedSequence(seed).generate_state(1, np.uint64)[0] >> np.uint64(1))
