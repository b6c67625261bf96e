"""One episode of a policy, summed up: its return and its worst tracking error per axis."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium
import numpy as np

from bwr_twin.arguments import CommandParser
from bwr_twin.model.machine import AXES, UNITS, to_display

Policy = Callable[[np.ndarray], np.ndarray]
PolicyFactory = Callable[[gymnasium.Env, int], Policy]  # (environment, seed) -> policy


@dataclass(frozen=True)
class EpisodeSummary:
    """What one episode came to.

    Attributes:
        episode_return: the sum of the rewards.
        steps: control periods stepped; simulated: s of path they cover.
        max_position_error: (3,) largest |reference - true joint| per axis (m, rad).
        ended: why the episode ended ("path end", "time limit", ...); "time limit" too for a
            gymnasium TimeLimit wrapper.
    """

    episode_return: float
    steps: int
    simulated: float
    max_position_error: np.ndarray
    ended: str

    def lines(self) -> list[str]:
        """The summary as printed lines, errors in m and degrees."""
        errors = ", ".join(f"{axis} {to_display(j, self.max_position_error[j]):.4g} {UNITS[j]}"
                           for j, axis in enumerate(AXES))
        return [f"episode return: {self.episode_return:.6g} over {self.steps} steps ({self.simulated:.2f} s)",
                f"max position error: {errors}",
                f"ended: {self.ended}"]


def run_episode(env: gymnasium.Env, policy: Policy, *, seed: int) -> EpisodeSummary:
    """Reset `env` with `seed` and step `policy(observation)` until the episode ends."""
    observation, info = env.reset(seed=seed)
    total, steps, worst = 0.0, 0, np.abs(info["position_error"])
    while True:
        observation, reward, terminated, truncated, info = env.step(policy(observation))
        total, steps = total + reward, steps + 1
        worst = np.maximum(worst, np.abs(info["position_error"]))
        if terminated or truncated:
            return EpisodeSummary(total, steps, info["time"], worst, info.get("ended", "time limit"))


def episode_command(description: str, make_policy: PolicyFactory, argv: list[str] | None = None) -> int:
    """The examples' command line: `--scene`, `--seed`, `--duration`. Runs one episode of the
    policy `make_policy(env, seed)` gives, in acceleration mode, and prints its summary; a bad
    scene gets one line and exit status 2."""
    from bwr_twin.errors import BwrError, exit_status

    parser = CommandParser(description=description)
    parser.add_argument("--scene", default="paper_individual_gains", help="scene file or shipped scene name")
    parser.add_argument("--seed", type=int, default=1, help="the episode's scene seed and the policy's (default 1)")
    parser.add_argument("--duration", type=float, help="stop after this many simulated seconds (default: the whole path)")
    args = parser.parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        parser.error(f"--duration must be > 0 s, got {args.duration}")

    def run() -> int:
        try:
            env = gymnasium.make("bwr_twin/Reclaim-v0", scene=args.scene, action_mode="acceleration",
                                 duration=args.duration)
        except ValueError as exc:  # a duration beyond the path: one line, as a bad scene gets
            raise BwrError(f"--{exc}") from None
        start = time.perf_counter()
        summary = run_episode(env, make_policy(env, args.seed), seed=args.seed)
        print("\n".join(summary.lines()))
        print(f"wall time: {time.perf_counter() - start:.1f} s")
        return 0

    return exit_status(run)
