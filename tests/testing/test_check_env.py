"""wfbench.testing.check_env: the checkers that fit run (tests/envs/test_envs.py runs them on every environment)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import wfbench
from wfbench.envs.gym_env import DispatchEnv
from wfbench.testing import check_env


class OutOfSpace(DispatchEnv):
    """A Dispatch-v0 whose observation leaves its space: ``globals`` above 1."""

    def _obs(self):
        obs = super()._obs()
        obs["globals"] = np.full_like(obs["globals"], 2.0)
        return obs


def test_an_observation_outside_its_space_fails_the_gymnasium_checker():
    env = OutOfSpace("small")
    env.spec = gymnasium.spec("wfbench/Dispatch-v0")  # as gymnasium.make would set it
    with pytest.raises(AssertionError, match="not within the observation space"):
        check_env(env)
    check_env(gymnasium.make("wfbench/Dispatch-v0", scenario="small"))  # the same environment, unbroken, passes


def test_a_checkers_warning_fails_unless_strict_is_off():
    with pytest.raises(UserWarning, match="Not able to test alternative render modes"):
        check_env(DispatchEnv("small"))  # made without gymnasium.make: no spec
    with pytest.warns(UserWarning, match="Not able to test alternative render modes"):
        assert len(check_env(DispatchEnv("small"), strict=False)) == 2


def test_anything_else_is_refused_in_one_line():
    with pytest.raises(TypeError, match=r"^check_env got str; allowed: a Gymnasium Env, a PettingZoo ParallelEnv or "
                                        r"AECEnv, or a function of no arguments that makes one$"):
        check_env("wfbench/Workforce-v0")
    with pytest.raises(TypeError, match=r"^check_env got Simulator; allowed"):
        check_env(lambda: wfbench.Simulator(wfbench.scenario("small"), [0]))
