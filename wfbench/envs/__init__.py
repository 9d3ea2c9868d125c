"""PettingZoo and Gymnasium environments around the batched simulator (B = 1).

The Gymnasium ids are registered by ``import wfbench`` (``wfbench.ENV_IDS``).
"""

from wfbench.envs.gym_env import DispatchEnv, WorkforceEnv
from wfbench.envs.parallel import WorkforceParallelEnv, env, parallel_env

__all__ = ["DispatchEnv", "WorkforceEnv", "WorkforceParallelEnv", "env", "parallel_env"]
