"""Stable-Baselines3 pieces for wfbench (``docs/sb3.md``).

:class:`WorkforceVecEnv` is an SB3 ``VecEnv`` over :class:`wfbench.envs.vector.WorkforceVectorEnv`
(one compiled call for B environments, MaskablePPO's masks, truncation at the horizon with the
terminal observation); :class:`EntitySetExtractor` pools facilities and people through
per-entity MLPs, so its weights fit any scenario size; :class:`SB3Policy` wraps a trained model
as a wfbench policy. This module imports torch and stable-baselines3 (the ``rl`` extra); nothing
in the core or the rest of ``wfbench.envs`` imports it, so ``import wfbench`` never loads torch.
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env import VecEnv

from wfbench.core.config import ScenarioConfig
from wfbench.core.observation_v2 import observe_v2
from wfbench.core.state import N_WORKFORCE_ACTIONS
from wfbench.envs.spaces import POSITIONING_LEVELS
from wfbench.envs.vector import WorkforceVectorEnv
from wfbench.scenarios.resolve import resolve_scenario

_N_STATUS = 6  # personnel status codes, wfbench.core.state.EMPTY..RETURNING


class WorkforceVecEnv(VecEnv):
    """An SB3 ``VecEnv`` of ``num_envs`` wfbench environments in one batched simulator.

    ``scenario``, ``num_envs``, ``kind``, ``fixed``, ``reward``, ``threads`` and
    ``obs_version`` are as in :class:`WorkforceVectorEnv`.

    Args:
        seed: the seed of the first episodes (environment i plays ``seed + i``); later
            episodes draw theirs as the single environment does. ``VecEnv.seed(s)``
            before a ``reset()`` sets it too.
    """

    def __init__(self, scenario: str | ScenarioConfig = "paper-64", num_envs: int = 8, kind: str = "workforce",
                 fixed: dict[str, Any] | None = None, reward: str = "nsw", threads: int | None = None,
                 seed: int | None = None, obs_version: int = 1):
        self.venv = WorkforceVectorEnv(scenario, num_envs, kind=kind, fixed=fixed, reward=reward, threads=threads,
                                       obs_version=obs_version)
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._first_seed = seed
        self._actions: np.ndarray | None = None
        self.render_mode = None

    @property
    def config(self) -> ScenarioConfig:
        return self.venv.config

    def reset(self):
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        if seeds is None and self._first_seed is not None:
            seeds, self._first_seed = [self._first_seed + i for i in range(self.num_envs)], None
        obs, infos = self.venv.reset(seed=seeds)
        self.reset_infos = [{"seed": int(infos["seed"][i])} for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        assert self._actions is not None, "step_async() first"
        obs, rewards, _, truncated, infos = self.venv.step(np.asarray(self._actions).reshape(self.num_envs, -1))
        self._actions = None
        out: list[dict[str, Any]] = [{"t": int(infos["t"][i]), "seed": int(infos["seed"][i])}
                                     for i in range(self.num_envs)]
        if truncated.any():
            for i in np.flatnonzero(truncated):
                out[i]["terminal_observation"] = infos["final_obs"][i]
                out[i]["TimeLimit.truncated"] = True
                out[i]["episode_seed"] = infos["final_info"][i]["seed"]
        return obs, rewards.astype(np.float32), truncated.copy(), out

    def action_masks(self) -> np.ndarray:
        """(num_envs, sum(nvec)) bool: the masks of every environment."""
        return self.venv.action_masks()

    def close(self) -> None:
        self.venv.close()

    # -- the per-environment interface SB3 and sb3-contrib call ------------------------------------
    def _targets(self, indices) -> list[int]:
        return list(self._get_indices(indices))

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        if attr_name == "action_masks":
            return [self.action_masks] * len(self._targets(indices))
        if attr_name == "render_mode":
            return [None] * len(self._targets(indices))
        value = getattr(self.venv, attr_name)  # AttributeError when there is none, as has_attr expects
        return [value] * len(self._targets(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise AttributeError(f"the environments of a {type(self).__name__} share one simulator; "
                             f"cannot set {attr_name!r} per environment")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        targets = self._targets(indices)
        if method_name == "action_masks":
            masks = self.action_masks()
            return [masks[i] for i in targets]
        raise AttributeError(f"{type(self).__name__} has no per-environment method {method_name!r}; "
                             "allowed: 'action_masks'")

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        return [False] * len(self._targets(indices))


def _scale(space: gym.spaces.Box) -> th.Tensor:
    """1 / the largest magnitude of each feature column of an entity Box (rows are entities)."""
    hi = np.maximum(np.abs(space.high), np.abs(space.low)).max(axis=0)
    return th.as_tensor(1.0 / np.maximum(hi, 1.0), dtype=th.float32)


def _mlp(n_in: int, hidden: int) -> th.nn.Sequential:
    return th.nn.Sequential(th.nn.Linear(n_in, hidden), th.nn.ReLU(), th.nn.Linear(hidden, hidden), th.nn.ReLU())


def _pool(h: th.Tensor, mask: th.Tensor) -> th.Tensor:
    """Masked mean and max over the entity axis of ``h`` (batch, entities, hidden); zeros where none is active."""
    m = mask.unsqueeze(-1)
    count = m.sum(dim=1).clamp(min=1.0)
    mean = (h * m).sum(dim=1) / count
    mx = h.masked_fill(m == 0, float("-inf")).amax(dim=1)
    mx = th.where(th.isfinite(mx), mx, th.zeros_like(mx))
    return th.cat([mean, mx], dim=1)


class EntitySetExtractor(BaseFeaturesExtractor):
    """Features of the entity sets: a per-entity MLP, masked mean and max pooling, the globals.

    Facility rows: the 7 facility features (scaled to [-1, 1] by the space's bounds) and
    ``requesting``; personnel rows: the 9 personnel features (scaled), the status one-hot,
    ``under_notice`` and ``dispatchable``. Empty slots (``facility_mask`` /
    ``personnel_mask`` 0) are left out of the pooling. The weights do not depend on M or N.

    Args:
        observation_space: the Dict space of a wfbench environment.
        hidden: width of the per-entity MLPs.
        features_dim: width of the output.
    """

    def __init__(self, observation_space: gym.spaces.Dict, hidden: int = 64, features_dim: int = 128):
        super().__init__(observation_space, features_dim)
        s = observation_space.spaces
        needed = ("facilities", "personnel", "facility_mask", "personnel_mask", "personnel_status",
                  "under_notice", "dispatchable", "requesting", "globals")
        missing = [k for k in needed if k not in s]
        if missing:
            raise ValueError(f"observation space lacks {missing}; allowed: a wfbench environment's Dict space")
        self.register_buffer("fac_scale", _scale(s["facilities"]))
        self.register_buffer("per_scale", _scale(s["personnel"]))
        n_fac, n_per = s["facilities"].shape[1] + 1, s["personnel"].shape[1] + _N_STATUS + 2
        n_glob = s["globals"].shape[0]
        self.fac = _mlp(n_fac, hidden)
        self.per = _mlp(n_per, hidden)
        self.out = th.nn.Sequential(th.nn.Linear(4 * hidden + n_glob, features_dim), th.nn.ReLU())

    def forward(self, obs: dict[str, th.Tensor]) -> th.Tensor:
        fac = th.cat([obs["facilities"] * self.fac_scale, obs["requesting"].unsqueeze(-1)], dim=-1)
        status = th.nn.functional.one_hot(obs["personnel_status"].long().clamp(0, _N_STATUS - 1), _N_STATUS)
        per = th.cat([obs["personnel"] * self.per_scale, status.float(), obs["under_notice"].unsqueeze(-1),
                      obs["dispatchable"].unsqueeze(-1)], dim=-1)
        pooled = [_pool(self.fac(fac), obs["facility_mask"]), _pool(self.per(per), obs["personnel_mask"])]
        return self.out(th.cat([*pooled, obs["globals"]], dim=1))


class SB3Policy:
    """A trained SB3 model (PPO or MaskablePPO on a :class:`WorkforceVecEnv`) as a wfbench policy.

    ``kind="workforce"`` makes all three decisions; ``kind="dispatch"`` makes the dispatch
    decision only (run it in ``policies.Composite`` beside the built-in workforce and
    positioning policies it was trained with). Actions are the model's deterministic
    choice, masked when the model is a MaskablePPO. A model trained on observation
    version 2 (its space has ``context``) is given :func:`~wfbench.core.observation_v2.observe_v2`
    of the observation.
    """

    def __init__(self, model: Any, config: str | ScenarioConfig, kind: str = "workforce", name: str = "sb3"):
        if kind not in ("workforce", "dispatch"):
            raise ValueError(f"kind {kind!r} is not allowed; allowed: workforce, dispatch")
        self.model, self.kind, self.name = model, kind, name
        self.config = resolve_scenario(config)  # a user's edge: the model and the scenario it plays
        self.M, self.N = self.config.max_facilities, self.config.max_personnel
        self.decisions = ("dispatch", "workforce", "positioning") if kind == "workforce" else ("dispatch",)
        self._keys = tuple(model.observation_space.spaces)
        self.observation_version = 2 if "context" in self._keys else 1
        self._masked = "action_masks" in inspect.signature(model.predict).parameters  # MaskablePPO

    def reset(self, seeds: Sequence[int]) -> None:
        pass

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        B, M = len(obs["facilities"]), self.M
        x = {k: obs[k] for k in self._keys} if self.observation_version == 1 else {
            k: v for k, v in observe_v2(obs).items() if k in self._keys}
        if self._masked:
            parts = [obs["dispatch_mask"].reshape(B, -1).astype(bool)]
            if self.kind == "workforce":
                parts += [obs["workforce_mask"].astype(bool), np.ones((B, 2 * M * POSITIONING_LEVELS), bool)]
            a, _ = self.model.predict(x, deterministic=True, action_masks=np.concatenate(parts, axis=1))
        else:
            a, _ = self.model.predict(x, deterministic=True)
        a = np.asarray(a, dtype=np.int64).reshape(B, -1)
        out = {"dispatch": np.ascontiguousarray(a[:, :M])}
        if self.kind == "workforce":
            out["workforce"] = np.clip(a[:, M], 0, N_WORKFORCE_ACTIONS - 1)
            out["positioning"] = (a[:, M + 1 :].astype(np.float64) / (POSITIONING_LEVELS - 1)).reshape(B, 2, M)
        return out
