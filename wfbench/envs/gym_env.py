"""Gymnasium environments ``wfbench/Workforce-v0`` (joint), ``wfbench/Workforce-v1`` and ``wfbench/Dispatch-v0``.

They observe a flat ``Dict`` of ``Box`` es (the shared observation plus action masks) and act
through a 1-D ``MultiDiscrete``, the shape SB3's PPO and MaskablePPO take (``action_masks()``).
:class:`WorkforceEnv` makes all three decisions (``[dispatch (M of 0..N), workforce (0..6),
positioning (2M of 0..10, weight = level / 10)]``); ``Workforce-v1`` is it with ``obs_version=2``
(:mod:`wfbench.core.observation_v2`). :class:`DispatchEnv` acts on the dispatch only, the other
decisions made by built-in policies (``fixed``), with ``reward="nsw"`` or ``"nsw-no-cost"``.
The options (``observation``, ``info``, ``obs_version``, ``render_mode``): ``docs/envs.md``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from wfbench.core.actions import ActionError
from wfbench.core.config import ScenarioConfig
from wfbench.core.reward import check_reward, step_reward
from wfbench.envs.parallel import WorkforceCore
from wfbench.envs.render import RENDER_MODES, HumanWindow, Rendering, check_render_mode
from wfbench.envs.spaces import (
    INFOS,
    OBSERVATIONS,
    POSITIONING_LEVELS,
    check_obs_version,
    check_option,
    joint_nvec,
    observation_space,
    shared_keys,
    shared_spaces,
    single,
    split_joint,
    versioned,
)
from wfbench.scenarios.resolve import resolve_scenario


class _Base(Rendering, gym.Env):
    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 8}

    def __init__(self, scenario: str | ScenarioConfig, fixed: dict[str, Any] | None, render_mode: str | None,
                 reward: str, observation: str, info: str, obs_version: int):
        check_render_mode(render_mode)
        check_reward(reward)
        self.obs_version = check_obs_version(obs_version)
        self.observation_kind = check_option("observation", observation, OBSERVATIONS)
        self.info_kind = check_option("info", info, INFOS)
        self._window: HumanWindow | None = None
        self.core = WorkforceCore(resolve_scenario(scenario), fixed)  # a name enters here (gymnasium.make)
        self.config = self.core.config
        self.render_mode = render_mode
        self.reward_kind = reward
        self.M, self.N = self.config.max_facilities, self.config.max_personnel

    def _dict_obs(self) -> dict[str, np.ndarray]:
        return single(versioned(self.core.obs, self.obs_version), self._keys)

    def _set_spaces(self, dict_space: spaces.Dict, masks: tuple[str, ...]) -> None:
        """The observation spaces; the observation's keys in the order of before (a Dict sorts its keys)."""
        self.dict_observation_space = dict_space
        self._keys = (*shared_keys(self.obs_version), *masks)
        self.observation_space = observation_space(dict_space, self.observation_kind)

    def _obs(self):
        obs = self._dict_obs()
        if self.observation_kind == "box":
            return spaces.flatten(self.dict_observation_space, obs)
        return obs

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        self.core.reset(seed)
        self._show()
        return self._obs(), self.core.info(self.info_kind)

    def _reward(self, nsw: float) -> float:
        if self.reward_kind == "nsw":
            return nsw
        return float(step_reward(self.reward_kind, np.array([nsw]), self.core.sim.state.last)[0])  # type: ignore

    def _step(self, given: dict[str, np.ndarray]):
        if self.core.sim is None:
            raise RuntimeError("call reset() before step()")
        nsw, _ = self.core.step(given)
        truncated = self.core.sim.done
        self._show()
        return self._obs(), self._reward(nsw), False, truncated, self.core.info(self.info_kind)

    def _check_vector(self, action: Any, n: int) -> np.ndarray:
        a = np.asarray(action)
        if a.shape != (n,):
            raise ActionError(f"action has shape {a.shape}, expected ({n},)")
        return a


class WorkforceEnv(_Base):
    """Joint decision: dispatch, workforce and positioning in one MultiDiscrete action."""

    def __init__(self, scenario: str | ScenarioConfig = "paper-64", render_mode: str | None = None,
                 reward: str = "nsw", observation: str = "dict", info: str = "flat", obs_version: int = 1):
        super().__init__(scenario, None, render_mode, reward, observation, info, obs_version)
        M, N = self.M, self.N
        self._set_spaces(spaces.Dict({
            **shared_spaces(self.config, self.obs_version),
            "dispatch_mask": spaces.Box(0, 1, shape=(M, N + 1), dtype=np.int8),
            "workforce_mask": spaces.Box(0, 1, shape=(7,), dtype=np.int8),
        }), ("dispatch_mask", "workforce_mask"))
        self.action_space = spaces.MultiDiscrete(joint_nvec(self.config))

    def action_masks(self) -> np.ndarray:
        """Flat mask over the MultiDiscrete choices (MaskablePPO's convention)."""
        obs = self.core.obs
        pos = np.ones(2 * self.M * POSITIONING_LEVELS, dtype=bool)
        return np.concatenate([obs["dispatch_mask"][0].ravel().astype(bool),
                               obs["workforce_mask"][0].astype(bool), pos])

    def step(self, action):
        return self._step(split_joint(self._check_vector(action, 1 + 3 * self.M), self.M))


class DispatchEnv(_Base):
    """Dispatch only; the workforce and positioning decisions are made by built-in policies."""

    def __init__(self, scenario: str | ScenarioConfig = "paper-64", fixed: dict[str, Any] | None = None,
                 render_mode: str | None = None, reward: str = "nsw", observation: str = "dict", info: str = "flat",
                 obs_version: int = 1):
        fixed = dict(fixed or {"workforce": "threshold", "positioning": "spatial"})
        if "dispatch" in fixed:
            raise ValueError("Dispatch-v0 learns the dispatch decision; fix only workforce and positioning")
        if set(fixed) != {"workforce", "positioning"}:
            raise ValueError(f"Dispatch-v0 needs fixed policies for workforce and positioning, got {sorted(fixed)}")
        super().__init__(scenario, fixed, render_mode, reward, observation, info, obs_version)
        M, N = self.M, self.N
        self._set_spaces(spaces.Dict({
            **shared_spaces(self.config, self.obs_version),
            "dispatch_mask": spaces.Box(0, 1, shape=(M, N + 1), dtype=np.int8),
        }), ("dispatch_mask",))
        self.action_space = spaces.MultiDiscrete(np.full(M, N + 1, dtype=np.int64))

    def action_masks(self) -> np.ndarray:
        return self.core.obs["dispatch_mask"][0].ravel().astype(bool)

    def step(self, action):
        return self._step({"dispatch": self._check_vector(action, self.M)})
