"""Speed of bwr_twin/Reclaim-v0: environment steps per second, single against vector, in one process.

    python tools/bench_gym.py [SCENE] [--envs 16] [--steps 2000] [--threads 0] [--repeat 3]

Steps the single environment `--steps` times, then the vector environment of `--envs`
sub-environments (one lockstep, MuJoCo's threads) `--steps` times, both in acceleration mode
with zero actions (computed-torque feed-forward: the machine stays on the path, no episode
ends). Keeps the best of `--repeat` of each (the machine is shared and noisy) and prints
environment steps per second for each, the vector-to-single ratio, the time of a reset, and the
single environment's floor: its lockstep of one alone, measured and advanced at zero force.
The timings alternate, so that a burst of load on the shared machine hits each figure alike.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import gymnasium
import numpy as np

import bwr_twin.gym  # noqa: F401  (registers the id)
from bwr_twin.config.scene import load_scene
from bwr_twin.errors import exit_status
from bwr_twin.gym import ENV_ID
from bwr_twin.sim.lockstep import Lockstep


def time_steps(env, actions: np.ndarray, steps: int, seed: int) -> float:
    """Wall time of `steps` steps from a reset with `seed`, s."""
    env.reset(seed=seed)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    return time.perf_counter() - start


def time_lockstep(scene, steps: int) -> float:
    """Wall time of `steps` periods of a lockstep of one, measured and advanced at zero force, s."""
    loop, command = Lockstep([scene], nthread=1), np.zeros((1, 3))
    start = time.perf_counter()
    for _ in range(steps):
        loop.measure()
        loop.advance(command)
    return time.perf_counter() - start


def time_reset(env, seed: int) -> float:
    """Wall time of one seeded reset, s."""
    start = time.perf_counter()
    env.reset(seed=seed)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="paper_individual_gains", help="scene file or shipped scene name")
    parser.add_argument("--envs", type=int, default=16, help="sub-environments of the vector environment (default 16)")
    parser.add_argument("--steps", type=int, default=2000,
                        help="steps per timing, at most the path's periods (default 2000: 20 s of path)")
    parser.add_argument("--threads", type=int, default=0, help="MuJoCo threads of the vector env (0: all cores)")
    parser.add_argument("--repeat", type=int, default=3, help="timings of each, the best kept (default 3)")
    args = parser.parse_args(argv)
    for name in ("envs", "steps", "repeat"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    return exit_status(lambda: _bench(args))


def _bench(args: argparse.Namespace) -> int:
    single = gymnasium.make(ENV_ID, scene=args.scene).unwrapped
    vector = gymnasium.make_vec(ENV_ID, num_envs=args.envs, scene=args.scene, nthread=args.threads)
    scene = load_scene(single.episodes.scene)
    samples = round(single.scales.duration / single.control_period) + 1
    if args.steps > samples:
        print(f"error: --steps {args.steps} is more than the path's {samples} control periods", file=sys.stderr)
        return 2
    print(f"scene {args.scene}, {args.steps} steps of {single.control_period} s, best of {args.repeat}, "
          f"{os.cpu_count()} cores")
    # Interleaved, so that a burst of load on the shared machine hits every figure alike.
    best = {"single": np.inf, "vector": np.inf, "lockstep": np.inf, "reset": np.inf, "vector reset": np.inf}
    for r in range(args.repeat):
        best["single"] = min(best["single"], time_steps(single, np.zeros(3, dtype=np.float32), args.steps, r))
        best["vector"] = min(best["vector"], time_steps(vector, np.zeros((args.envs, 3), dtype=np.float32),
                                                        args.steps, r))
        best["lockstep"] = min(best["lockstep"], time_lockstep(scene, args.steps))
        best["reset"] = min(best["reset"], time_reset(single, r))
        best["vector reset"] = min(best["vector reset"], time_reset(vector, r))
    single_rate, vector_rate = args.steps / best["single"], args.steps * args.envs / best["vector"]
    floor = args.steps / best["lockstep"]
    print(f"single env: {single_rate:,.0f} env steps/s")
    print(f"vector env ({args.envs} envs, one lockstep): {vector_rate:,.0f} env steps/s")
    print(f"vector / single: {vector_rate / single_rate:.2f}")
    print(f"lockstep of one alone: {floor:,.0f} periods/s (the single env reaches {single_rate / floor:.0%} of it)")
    print(f"reset: single {best['reset'] * 1e3:.1f} ms, vector of {args.envs} {best['vector reset'] * 1e3:.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
