"""Checks to run before you submit, shipped in the package as ``pettingzoo.test`` ships PettingZoo's.

:func:`check_env` runs the installed RL libraries' own environment checkers (Gymnasium's and
Stable-Baselines3's ``check_env``, PettingZoo's API and seed tests) with their warnings as
errors (``docs/envs.md``, "Checking an environment"). :func:`check_policy` runs a policy through
the protocol on a few seeds (actions, masks, the same actions for the same seed) and raises a
one-line :class:`PolicyCheckError` at the first problem (``docs/policies.md``, "Checking a policy
before you submit"). Modules: ``env`` and ``policy``, neither importing the other.
"""

from wfbench.testing.env import ADVISORIES, check_env
from wfbench.testing.policy import PolicyCheckError, check_policy

__all__ = ["ADVISORIES", "PolicyCheckError", "check_env", "check_policy"]
