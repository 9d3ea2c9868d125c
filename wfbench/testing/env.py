"""The RL libraries' own environment checkers, run as wfbench's tests run them.

:func:`check_env` takes a Gymnasium environment, a PettingZoo Parallel or AEC
environment, or a function of no arguments that makes one (then PettingZoo's seed test
runs too, on two environments it makes). Every warning a checker gives is an error
(``strict=True``), except :data:`ADVISORIES`: advice that wfbench's environments do not
follow on purpose.
"""

from __future__ import annotations

import importlib.util
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

# The checkers' advice that wfbench's environments do not follow on purpose: entity features are (M, 7) and
# (N, 9) arrays (docs/model.md), the observation is a Dict, the agents are named by their decision.
ADVISORIES = (
    "Your observation .* has an unconventional shape",  # SB3
    "Observation is not a NumPy array",  # PettingZoo, on a Dict observation
    "Observation space for each agent probably should be",  # PettingZoo
    "Action space for each agent probably should be",  # PettingZoo
    "We recommend agents to be named in the format",  # PettingZoo
)
ENV_KINDS = "a Gymnasium Env, a PettingZoo ParallelEnv or AECEnv, or a function of no arguments that makes one"


def check_env(env: Any, num_cycles: int = 50, strict: bool = True) -> tuple[str, ...]:
    """Run the checkers that fit ``env`` and are installed; return their names, in the order they ran.

    - A Gymnasium ``Env``: Gymnasium's ``check_env`` and, where stable-baselines3 is
      installed, SB3's ``check_env``, both on ``env.unwrapped`` (Gymnasium's advice: its
      checker wants the environment without the wrappers ``gymnasium.make`` adds).
    - A PettingZoo ``ParallelEnv``: ``parallel_api_test`` for ``num_cycles`` steps; an
      ``AECEnv``: ``api_test``.
    - A function of no arguments that makes one of those: the checks of what it makes
      and, for a PettingZoo environment, PettingZoo's ``parallel_seed_test`` or
      ``seed_test`` (two environments of the same seed must play the same; Gymnasium's
      checker tests its seeding itself).

    Args:
        env: the environment, or a function of no arguments that makes one.
        num_cycles: steps of PettingZoo's API tests.
        strict: every warning a checker gives fails the check, except :data:`ADVISORIES`.

    Returns:
        The checkers run, as ``module.function`` names.

    Raises:
        TypeError: ``env`` is none of the kinds above.
        AssertionError, Warning: what a checker raises (with ``strict``, its warnings too).
    """
    factory: Callable[[], Any] | None = None
    if callable(env) and not isinstance(env, (gymnasium.Env, ParallelEnv, AECEnv)):
        factory, env = env, env()
    ran: list[str] = []
    with warnings.catch_warnings():
        if strict:
            warnings.simplefilter("error")
            for pattern in ADVISORIES:
                warnings.filterwarnings("ignore", message=pattern)
        if isinstance(env, gymnasium.Env):
            from gymnasium.utils.env_checker import check_env as gymnasium_check_env

            gymnasium_check_env(env.unwrapped)
            ran.append("gymnasium.utils.env_checker.check_env")
            if importlib.util.find_spec("stable_baselines3") is not None:
                from stable_baselines3.common.env_checker import check_env as sb3_check_env

                sb3_check_env(env.unwrapped)
                ran.append("stable_baselines3.common.env_checker.check_env")
        elif isinstance(env, ParallelEnv):
            parallel_api_test(env, num_cycles=num_cycles)
            ran.append("pettingzoo.test.parallel_api_test")
            if factory is not None:
                parallel_seed_test(factory)
                ran.append("pettingzoo.test.parallel_seed_test")
        elif isinstance(env, AECEnv):
            api_test(env, num_cycles=num_cycles)
            ran.append("pettingzoo.test.api_test")
            if factory is not None:
                seed_test(factory)
                ran.append("pettingzoo.test.seed_test")
        else:
            raise TypeError(f"check_env got {type(env).__name__}; allowed: {ENV_KINDS}")
    return tuple(ran)
