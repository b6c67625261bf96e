"""Many seeds of `bwr_twin/Reclaim-v0` at once, their runs in one lockstep (MuJoCo's threaded batch).

    envs = gymnasium.make_vec("bwr_twin/Reclaim-v0", num_envs=16, scene="paper_individual_gains")

Sub-environment i is the single environment with its own seed: `reset(seed=s)` gives it s + i,
a list gives each its own, and each later episode draws its seed from the sub-environment's
generator exactly as the single environment's `reset()` does. So a sub-environment's episodes
are, bit for bit, those of `gymnasium.make` with the same seeds and actions.

Autoreset is gymnasium's next-step mode (`AutoresetMode.NEXT_STEP`): the step after a
sub-environment terminates or truncates starts its next episode, ignores its action and returns
its first observation, with reward 0 and neither flag set.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from bwr_twin.gym.actions import DEFAULT_ACCELERATION_SCALE, checked_actions
from bwr_twin.gym.env import DEFAULT_ERROR_SCALE
from bwr_twin.gym.episodes import Episodes
from bwr_twin.gym.reward import DEFAULT_WEIGHTS
from bwr_twin.gym.spaces import ENV_ID, action_space, episode_seed, observation_space
from bwr_twin.shipped import DEFAULT_SCENE


class ReclaimVectorEnv(VectorEnv):
    """`num_envs` sub-environments on one lockstep. Arguments as `ReclaimEnv`'s, and `nthread`,
    MuJoCo's threads (0: all cores, never more than num_envs). Infos hold, per sub-environment,
    `time` (s), `position_error` (3,) (m, rad), `seed`, and `ended` where an episode ended.
    Actions are (num_envs, 3), finite; it cannot be pickled or copied, as `ReclaimEnv`."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, scene: str | Path = DEFAULT_SCENE, *, action_mode: str = "acceleration",
                 force_scale: Sequence[float] | None = None,
                 acceleration_scale: float = DEFAULT_ACCELERATION_SCALE,
                 error_scale: float = DEFAULT_ERROR_SCALE, reward_weights: Sequence[float] = DEFAULT_WEIGHTS,
                 overrides: Mapping[str, Any] | None = None, nthread: int = 0, duration: float | None = None,
                 instruments: bool = False):
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.num_envs = num_envs
        self.episodes = Episodes(scene, num_envs, action_mode=action_mode, force_scale=force_scale,
                                 acceleration_scale=acceleration_scale, error_scale=error_scale,
                                 reward_weights=reward_weights, overrides=overrides, nthread=nthread,
                                 duration=duration, instruments=instruments)
        self.scales = self.episodes.scales
        self.drive = self.episodes.drive
        self.control_period = self.episodes.period
        self.single_observation_space = observation_space(self.scales.size)
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._generators: list[np.random.Generator | None] = [None] * num_envs
        self._autoreset = np.zeros(num_envs, dtype=bool)

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        """Start every sub-environment's path again, all in one lockstep."""
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} sub-environments")
        for i, s in enumerate(seeds):
            if s is not None or self._generators[i] is None:
                self._generators[i], _ = seeding.np_random(s)
        self.episodes.start(range(self.num_envs), [episode_seed(g, s) for g, s in zip(self._generators, seeds)])
        self._autoreset[:] = False
        return self.episodes.observation.copy(), self._infos({})

    def step(self, actions):
        restart = np.flatnonzero(self._autoreset)
        where = f"{self.episodes.where}, a vector of {self.num_envs}"
        actions = checked_actions(actions, (self.num_envs, 3), where, rows="sub-environment")
        outcome = self.episodes.step(actions)
        if len(restart):
            self.episodes.start(restart, [episode_seed(self._generators[i], None) for i in restart])
        self._autoreset = outcome.terminated | outcome.truncated
        return (self.episodes.observation.copy(), outcome.reward, outcome.terminated, outcome.truncated,
                self._infos(outcome.ended))

    def __reduce_ex__(self, protocol):
        raise TypeError(f"a vector environment of {ENV_ID} cannot be pickled or copied: it holds compiled "
                        f"MuJoCo models and runs under way; make another with gymnasium.make_vec({ENV_ID!r}, "
                        f"num_envs={self.num_envs}, ...) and the same arguments (docs/gym.md)")

    def _infos(self, ended: dict[int, str]) -> dict[str, Any]:
        everyone = np.ones(self.num_envs, dtype=bool)
        episodes = self.episodes
        infos = {"time": episodes.elapsed.copy(), "_time": everyone,
                 "position_error": episodes.error.copy(), "_position_error": everyone.copy(),
                 "seed": episodes.seed.copy(), "_seed": everyone.copy()}
        if ended:
            infos["ended"] = np.full(self.num_envs, None, dtype=object)
            infos["_ended"] = np.zeros(self.num_envs, dtype=bool)
            for slot, why in ended.items():
                infos["ended"][slot], infos["_ended"][slot] = why, True
        return infos
