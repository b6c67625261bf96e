"""A PD policy in acceleration mode on bwr_twin/Reclaim-v0: computed torque, the agent's way.

    python examples/gym_pd.py [--scene paper_individual_gains] [--seed 1] [--duration S]

Each period the policy reads the tracking error and its rate from the observation, in SI
through the environment's scales, and asks for the acceleration kp e + kd de/dt on top of the
reference's (kp = 4 1/s^2, kd = 4 1/s: 2 rad/s, critically damped, as the shipped
computed-torque scenes). Prints the episode return and the largest position error per axis.
"""

from __future__ import annotations

import sys

import gymnasium
import numpy as np

import bwr_twin.gym  # noqa: F401  (registers bwr_twin/Reclaim-v0)
from bwr_twin.gym.evaluate import Policy, episode_command
from bwr_twin.gym.scales import ERROR, REFERENCE_VELOCITY, VELOCITY

KP, KD = 4.0, 4.0  # 1/s^2, 1/s


def pd_policy(env: gymnasium.Env, seed: int) -> Policy:
    """kp e + kd de/dt in SI, through the environment's scales, as a share of its acceleration scale."""
    scales, acceleration_scale = env.unwrapped.scales, env.unwrapped.drive.scale

    def pd(observation: np.ndarray) -> np.ndarray:
        error = observation[ERROR] * scales.error  # m, rad
        error_rate = (observation[REFERENCE_VELOCITY] - observation[VELOCITY]) * scales.velocity  # m/s, rad/s
        return ((KP * error + KD * error_rate) / acceleration_scale).astype(np.float32)

    return pd


if __name__ == "__main__":
    sys.exit(episode_command(__doc__.split("\n\n")[0], pd_policy))
