"""A random policy in acceleration mode on bwr_twin/Reclaim-v0: the floor any agent must beat.

    python examples/gym_random.py [--scene paper_individual_gains] [--seed 1] [--duration S]

Each period draws an action uniformly from [-1, 1]^3 (the action space seeded with `--seed`):
a random acceleration of up to the environment's acceleration scale on top of the reference's.
Prints the episode return and the largest position error per axis.
"""

from __future__ import annotations

import sys

import gymnasium

import bwr_twin.gym  # noqa: F401  (registers bwr_twin/Reclaim-v0)
from bwr_twin.gym.evaluate import Policy, episode_command


def random_policy(env: gymnasium.Env, seed: int) -> Policy:
    """Uniform actions from the action space, seeded."""
    env.action_space.seed(seed)
    return lambda observation: env.action_space.sample()


if __name__ == "__main__":
    sys.exit(episode_command(__doc__.split("\n\n")[0], random_policy))
