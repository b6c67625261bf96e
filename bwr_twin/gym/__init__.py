"""Gymnasium environments of the twin: a learning agent in the controller's slot.

    import gymnasium, bwr_twin.gym
    env = gymnasium.make("bwr_twin/Reclaim-v0", scene="paper_individual_gains")
    envs = gymnasium.make_vec("bwr_twin/Reclaim-v0", num_envs=16, scene="paper_individual_gains")

Importing this package registers the id. docs/gym.md has the contract.
"""

from gymnasium.envs.registration import register, registry

from bwr_twin.gym.env import ReclaimEnv
from bwr_twin.gym.spaces import ENV_ID
from bwr_twin.gym.vector import ReclaimVectorEnv

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="bwr_twin.gym.env:ReclaimEnv",
             vector_entry_point="bwr_twin.gym.vector:ReclaimVectorEnv")

__all__ = ["ENV_ID", "ReclaimEnv", "ReclaimVectorEnv"]
