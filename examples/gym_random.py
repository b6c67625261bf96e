"""A random policy in acceleration mode on bwr_twin/Reclaim-v0: the floor any agent must beat.

    python examples/gym_random.py [--scene paper_individual_gains] [--seed 1] [--duration S]

Each period draws an action uniformly from [-1, 1]^3 (the action space seeded with `--seed`):
a random acceleration of up to the environment's acceleration scale on top of the reference's.
Prints the episode return and the largest position error per axis.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium

import bwr_twin.gym  # noqa: F401  (registers bwr_twin/Reclaim-v0)
from bwr_twin.errors import exit_status
from bwr_twin.gym.evaluate import run_episode


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="paper_individual_gains", help="scene file or shipped scene name")
    parser.add_argument("--seed", type=int, default=1, help="the episode's scene seed and the policy's (default 1)")
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
    env.action_space.seed(args.seed)
    start = time.perf_counter()
    summary = run_episode(env, lambda observation: env.action_space.sample(), seed=args.seed)
    print("\n".join(summary.lines()))
    print(f"wall time: {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
