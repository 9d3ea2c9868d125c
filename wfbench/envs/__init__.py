"""PettingZoo and Gymnasium environments around the batched simulator (B = 1)."""

from wfbench.envs.gym_env import DispatchEnv, WorkforceEnv, register_envs
from wfbench.envs.parallel import WorkforceParallelEnv, env, parallel_env

__all__ = ["DispatchEnv", "WorkforceEnv", "WorkforceParallelEnv", "env", "parallel_env", "register_envs"]
