"""A PD policy in acceleration mode on bwr_twin/Reclaim-v0: computed torque, the agent's way.

    python examples/gym_pd.py [--scene paper_individual_gains] [--seed 1] [--duration S]

Each period the policy reads the tracking error and its rate from the observation, in SI
through the environment's scales, and asks for the acceleration kp e + kd de/dt on top of the
reference's (kp = 4 1/s^2, kd = 4 1/s: 2 rad/s, critically damped, as the shipped
computed-torque scenes). Prints the episode return and the largest position error per axis.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium
import numpy as np

import bwr_twin.gym  # noqa: F401  (registers bwr_twin/Reclaim-v0)
from bwr_twin.errors import exit_status
from bwr_twin.gym.evaluate import run_episode
from bwr_twin.gym.scales import ERROR, REFERENCE_VELOCITY, VELOCITY

KP, KD = 4.0, 4.0  # 1/s^2, 1/s


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="paper_individual_gains", help="scene file or shipped scene name")
    parser.add_argument("--seed", type=int, default=1, help="the episode's scene seed (default 1)")
    parser.add_argument("--duration", type=float, help="stop after this many simulated seconds (default: the whole path)")
    args = parser.parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        parser.error(f"--duration must be > 0 s, got {args.duration}")
    return exit_status(lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    env = gymnasium.make("bwr_twin/Reclaim-v0", scene=args.scene, action_mode="acceleration")
    if args.duration is not None:
        steps = max(1, round(args.duration / env.unwrapped.control_period))
        env = gymnasium.wrappers.TimeLimit(env, max_episode_steps=steps)
    scales, acceleration_scale = env.unwrapped.scales, env.unwrapped.drive.scale

    def pd(observation: np.ndarray) -> np.ndarray:
        error = observation[ERROR] * scales.error  # m, rad
        error_rate = (observation[REFERENCE_VELOCITY] - observation[VELOCITY]) * scales.velocity  # m/s, rad/s
        return ((KP * error + KD * error_rate) / acceleration_scale).astype(np.float32)

    start = time.perf_counter()
    summary = run_episode(env, pd, seed=args.seed)
    print("\n".join(summary.lines()))
    print(f"wall time: {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
