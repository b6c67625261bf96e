"""`bwr_twin/Reclaim-v0`: one reclaim of a scene's path, the agent in the controller's slot.

Each step is one control period of the scene (0.01 s for the shipped scenes): the agent sees
the encoders and the reference (`bwr_twin.gym.scales`), its action sets the drive forces
(`bwr_twin.gym.actions`), and it earns the negative weighted square of the true tracking error
(`bwr_twin.gym.reward`). The episode terminates after the path's last period and is truncated
when a joint leaves the machine's operating envelope, the simulation diverges or `duration` s
have passed. docs/gym.md has the whole contract.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium

from bwr_twin.gym.actions import DEFAULT_ACCELERATION_SCALE, as_action
from bwr_twin.gym.episodes import Episodes
from bwr_twin.gym.reward import DEFAULT_WEIGHTS
from bwr_twin.gym.spaces import ENV_ID, action_space, episode_seed, observation_space
from bwr_twin.shipped import DEFAULT_SCENE

DEFAULT_ERROR_SCALE = 0.1  # m at the CP: the paper's controller keeps within 2 cm


class ReclaimEnv(gymnasium.Env):
    """One environment: a lockstep of one run per episode.

    Args:
        scene: a scene file, or the name of a shipped one (`paper_individual_gains`).
        action_mode: "acceleration" (default) or "force".
        force_scale: (3,) N, N m, N m that +-1 means in force mode; default the drive ratings.
        acceleration_scale: m/s^2 at the CP that +-1 adds in acceleration mode.
        error_scale: m at the CP: the observation's and the reward's error scale.
        reward_weights: (3,) travel, slew, luff weights of the reward.
        overrides: scene keys to replace, as `load_scene` takes them (not `simulation.seed`,
            which each episode's seed sets).
        duration: s an episode lasts at most, then truncated with info["ended"] "time limit";
            None (default): the whole path.
        instruments: add the belt scale (t/h) and the wheel motor's current (A) to the
            observation, entries 19 and 20 (bwr_twin.gym.scales); a scene without both is refused
            with a SceneError naming it.

    Episodes beyond the twin's bounds (more than 12 h of computing, half of the memory, as
    `bwr_twin.run` estimates a run) are refused when the environment is made. An environment
    cannot be pickled or copied (it holds compiled MuJoCo models and a run under way): make
    another with the same arguments.

    Attributes:
        scales: the observation's scales (`bwr_twin.gym.scales.Scales`), to read observations in SI.
        drive: how actions become forces: `drive.scale` (3,) m/s^2, rad/s^2 in acceleration
            mode; `drive.low`, `drive.high` (3,) N, N m in force mode.
        control_period: s, one step.
    """

    metadata = {"render_modes": []}

    def __init__(self, scene: str | Path = DEFAULT_SCENE, *, action_mode: str = "acceleration",
                 force_scale: Sequence[float] | None = None,
                 acceleration_scale: float = DEFAULT_ACCELERATION_SCALE,
                 error_scale: float = DEFAULT_ERROR_SCALE, reward_weights: Sequence[float] = DEFAULT_WEIGHTS,
                 overrides: Mapping[str, Any] | None = None, duration: float | None = None,
                 instruments: bool = False):
        self.episodes = Episodes(scene, 1, action_mode=action_mode, force_scale=force_scale,
                                 acceleration_scale=acceleration_scale, error_scale=error_scale,
                                 reward_weights=reward_weights, overrides=overrides, nthread=1,
                                 duration=duration, instruments=instruments)
        self.scales = self.episodes.scales
        self.drive = self.episodes.drive
        self.control_period = self.episodes.period
        self.observation_space = observation_space(self.scales.size)
        self.action_space = action_space()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start the path again; `seed` is the scene seed (encoders, disturbances, gusts)."""
        super().reset(seed=seed)
        self.episodes.start([0], [episode_seed(self.np_random, seed)])
        return self.episodes.observation[0].copy(), self._info()

    def step(self, action):
        episodes = self.episodes
        action = as_action(action, episodes.where)
        if not episodes.is_running(0):
            raise RuntimeError("the episode has ended (terminated or truncated): call reset() first")
        reward, terminated, truncated, ended = episodes.step_one(action)
        info = self._info()
        if ended is not None:
            info["ended"] = ended
        return episodes.observation[0].copy(), reward, terminated, truncated, info

    def __reduce_ex__(self, protocol):
        raise TypeError(f"{ENV_ID} cannot be pickled or copied: it holds compiled MuJoCo models and a run "
                        f"under way; make another with gymnasium.make({ENV_ID!r}, ...) and the same arguments "
                        "(docs/gym.md)")

    def _info(self) -> dict[str, Any]:
        """time: s since the path's start; position_error: (3,) true reference - joint (m, rad);
        seed: the episode's scene seed."""
        episodes = self.episodes
        return {"time": float(episodes.elapsed[0]), "position_error": episodes.error[0].copy(),
                "seed": int(episodes.seed[0])}
