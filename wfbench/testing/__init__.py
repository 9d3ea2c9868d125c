"""Checks to run before you submit, shipped in the package as ``pettingzoo.test`` ships PettingZoo's.

- :func:`check_env`: the installed RL libraries' own environment checkers (Gymnasium's
  ``check_env``, Stable-Baselines3's ``check_env``, PettingZoo's ``parallel_api_test``,
  ``api_test`` and seed tests) on a wfbench environment or one of your own, with their
  warnings as errors.
- :func:`check_policy`: your policy through the policy protocol (``docs/policies.md``)
  on a few seeds: the keys, shapes, types and ranges of its actions, the action masks,
  and the same actions for the same seed (again, and alone); the first problem raises a
  :class:`PolicyCheckError` whose message is one line.

Modules: ``env`` (the environment checkers) and ``policy`` (the policy check), neither
importing the other.
"""

from wfbench.testing.env import ADVISORIES, check_env
from wfbench.testing.policy import PolicyCheckError, check_policy

__all__ = ["ADVISORIES", "PolicyCheckError", "check_env", "check_policy"]
