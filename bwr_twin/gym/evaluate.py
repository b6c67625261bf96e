"""One episode of a policy, summed up: its return and its worst tracking error per axis."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import gymnasium
import numpy as np

from bwr_twin.model.machine import AXES, UNITS, to_display

Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class EpisodeSummary:
    """What one episode came to.

    Attributes:
        episode_return: the sum of the rewards.
        steps: control periods stepped; simulated: s of path they cover.
        max_position_error: (3,) largest |reference - true joint| per axis (m, rad).
        ended: why the episode ended ("path end", ...), or "time limit" for a TimeLimit wrapper.
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
