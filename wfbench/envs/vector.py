"""A Gymnasium ``VectorEnv`` over one batched :class:`~wfbench.core.simulator.Simulator`.

``WorkforceVectorEnv(scenario, num_envs, kind="workforce")`` is B copies of
``wfbench/Workforce-v0`` (``kind="dispatch"``: ``wfbench/Dispatch-v0``; ``obs_version=2``:
``wfbench/Workforce-v1``) stepped by one compiled call, with the single environments' spaces and
reward; ``gymnasium.make_vec`` builds it. Autoreset is same-step by default, through the partial
``Simulator.reset(indices, seeds)``, or ``autoreset_mode="next_step"``. Seeds follow the single
environments', so it replays ``SyncVectorEnv`` bit for bit (``tests/envs/test_vector_env.py``);
``kind="dispatch"`` environments are always reset together. ``docs/sb3.md``, "Episodes, autoreset
and seeds".
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from wfbench.core.actions import ActionError, validate_actions
from wfbench.core.config import ScenarioConfig
from wfbench.core.reward import check_reward, step_reward
from wfbench.core.simulator import Simulator
from wfbench.envs.gym_env import DispatchEnv, WorkforceEnv
from wfbench.envs.spaces import POSITIONING_LEVELS, flatten_batch, split_joint, versioned
from wfbench.scenarios.resolve import resolve_scenario

KINDS = {"workforce": WorkforceEnv, "dispatch": DispatchEnv}
AUTORESET_MODES = {  # the autoreset_mode option: a name, the AutoresetMode or its value
    **{m: m for m in (AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP)},
    "same_step": AutoresetMode.SAME_STEP, "next_step": AutoresetMode.NEXT_STEP,
    AutoresetMode.SAME_STEP.value: AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP.value: AutoresetMode.NEXT_STEP,
}
_SEED_HIGH = 2**31 - 1  # the single environments draw their next seeds below this


class WorkforceVectorEnv(VectorEnv):
    """``num_envs`` workforce environments in one batched simulator (see the module docstring)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, scenario: str | ScenarioConfig = "paper-64", num_envs: int = 8, kind: str = "workforce",
                 fixed: dict[str, Any] | None = None, reward: str = "nsw", threads: int | None = None,
                 observation: str = "dict", autoreset_mode: str | AutoresetMode = AutoresetMode.SAME_STEP,
                 render_mode: None = None, obs_version: int = 1):
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r} is not supported by the vector environment; allowed: None")
        if autoreset_mode not in AUTORESET_MODES:
            raise ValueError(f"autoreset_mode={autoreset_mode!r} is not allowed; allowed: 'same_step', 'next_step' "
                             "or the AutoresetMode (or its value)")
        self.autoreset_mode = AUTORESET_MODES[autoreset_mode]
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        if not (type(num_envs) is int and num_envs >= 1):
            raise ValueError(f"num_envs = {num_envs!r} is not allowed; allowed: an integer >= 1")
        if kind not in KINDS:
            raise ValueError(f"kind {kind!r} is not allowed; allowed: {', '.join(KINDS)}")
        check_reward(reward)
        if kind == "workforce" and fixed:
            raise ValueError("kind='workforce' learns every decision; fix decisions with kind='dispatch'")
        scenario = resolve_scenario(scenario)  # a name enters here (gymnasium.make_vec, WorkforceVecEnv)
        single = (DispatchEnv(scenario, fixed=fixed, observation=observation, obs_version=obs_version)
                  if kind == "dispatch" else WorkforceEnv(scenario, observation=observation, obs_version=obs_version))
        self.observation_kind = observation
        self.obs_version = single.obs_version
        self.config = single.config
        self.kind, self.reward_kind = kind, reward
        self.fixed = single.core.fixed  # the built-in policies the single environment resolved (none for workforce)
        self.num_envs = num_envs
        self.M, self.N = self.config.max_facilities, self.config.max_personnel
        self.single_observation_space = single.observation_space
        self.single_action_space = single.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._dict_space = single.dict_observation_space
        self._keys = tuple(self._dict_space.spaces)
        self._pending = np.zeros(num_envs, dtype=bool)  # next-step mode: rows whose reset the next step returns
        self._threads = threads
        self.sim: Simulator | None = None
        self._obs: dict[str, np.ndarray] | None = None
        self._seed_rngs: list[np.random.Generator] = []
        self.closed = False

    # -- episodes ----------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        """Reset every environment (or, ``options={"reset_mask": mask}``, those of the boolean mask).

        ``seed``: an integer s (environment i plays s + i), a list of one seed per reset
        environment, or None (seeds drawn from ``self.np_random``, or for a masked reset each
        environment's own seed sequence).
        """
        mask = None if options is None else options.get("reset_mask")
        if mask is not None:
            if self.sim is None:
                raise RuntimeError("call reset() without a reset_mask first")
            mask = np.asarray(mask)
            if mask.dtype != bool or mask.shape != (self.num_envs,):
                raise ValueError(f"options['reset_mask'] has dtype {mask.dtype} and shape {mask.shape}; "
                                 f"allowed: a boolean array of shape ({self.num_envs},)")
            if self.fixed and not mask.all():
                raise ValueError("kind='dispatch' resets its environments together: the fixed policies keep "
                                 "memory per environment (cooldowns, smoothed demand) that a reset of part of "
                                 "their batch would wipe; allowed: a reset_mask of all True, or kind='workforce'")
            idx = np.flatnonzero(mask)
        else:
            idx = np.arange(self.num_envs)
        if seed is None:
            if mask is None:
                super().reset(seed=None)
                seeds = [int(s) for s in self.np_random.integers(0, _SEED_HIGH, size=self.num_envs)]
            else:
                seeds = [int(self._seed_rngs[i].integers(0, _SEED_HIGH)) for i in idx]
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            super().reset(seed=int(seed))
            seeds = [int(seed) + i for i in range(len(idx))]
        else:
            seeds = list(seed)
            if len(seeds) != len(idx):
                raise ValueError(f"{len(seeds)} seeds for {len(idx)} environments; allowed: one seed per "
                                 "environment reset, an integer or None")
        for s in seeds:
            if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
                raise ValueError(f"seed = {s!r} is not allowed; allowed: an integer >= 0")
        if mask is None:
            self.sim = Simulator(self.config, seeds, keep_series=False, threads=self._threads)
            self._seed_rngs = [np.random.default_rng(s) for s in seeds]
            self._obs = self.sim.reset()
        else:
            for i, s in zip(idx, seeds, strict=True):
                self._seed_rngs[i] = np.random.default_rng(s)
            self._obs = self.sim.reset(indices=idx, seeds=seeds)
        self._pending[idx] = False
        self._reset_fixed()
        return self._copy_obs(), self._infos()

    def _reset_fixed(self) -> None:
        assert self.sim is not None
        for p in {id(p): p for p in self.fixed.values()}.values():
            p.reset(self.sim.seeds.copy())

    def _copy_obs(self, obs: dict[str, np.ndarray] | None = None):
        obs = self._obs if obs is None else obs
        assert obs is not None
        obs = versioned(obs, self.obs_version)
        if self.observation_kind == "box":
            return flatten_batch(self._dict_space, obs)
        return {k: obs[k].copy() for k in self._keys}

    def _infos(self) -> dict[str, Any]:
        assert self.sim is not None
        ones = np.ones(self.num_envs, dtype=bool)
        return {"t": self.sim.state.t.copy(), "_t": ones, "seed": self.sim.seeds.copy(), "_seed": ones}

    # -- steps -------------------------------------------------------------------------------
    def _actions(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The batched simulator actions of a (B, n) MultiDiscrete action, checked."""
        B, M = self.num_envs, self.M
        a = np.asarray(actions)
        n = self.single_action_space.shape[0]
        if a.shape != (B, n):
            raise ActionError(f"action has shape {a.shape}, expected ({B}, {n})")
        if a.dtype.kind not in "iu":
            raise ActionError(f"action has dtype {a.dtype}; allowed: integers")
        given: dict[str, Any] = {"dispatch": np.ascontiguousarray(a[:, :M], dtype=np.int64)}
        if self.kind == "workforce":
            joint = split_joint(a, M)
            given["workforce"] = np.ascontiguousarray(joint["workforce"], dtype=np.int64)
            given["positioning"] = joint["positioning"]
        else:
            assert self._obs is not None
            cache: dict[int, dict[str, np.ndarray]] = {}
            for agent, p in self.fixed.items():
                if id(p) not in cache:
                    cache[id(p)] = p.act(self._obs)
                given[agent] = cache[id(p)][agent]
        return validate_actions(given, B, M, self.N)

    def step(self, actions):
        if self.sim is None:
            raise RuntimeError("call reset() before step()")
        d, w, p = self._actions(actions)
        pending = self._pending.copy()
        if pending.all():  # next-step mode: every row starts its new episode, already reset
            self._pending[:] = False
            zeros = np.zeros(self.num_envs, dtype=bool)
            return self._copy_obs(), np.zeros(self.num_envs), zeros, zeros.copy(), self._infos()
        if pending.any():  # those rows play no-ops, then are reset again on the same seeds
            d, w = d.copy(), w.copy()  # they may be the caller's arrays
            d[pending], w[pending] = self.N, 0
        self.sim.check_ready()
        nsw, obs = self.sim.step_observe_checked(d, w, p)
        rewards = step_reward(self.reward_kind, nsw, self.sim.state.last)
        self._obs = obs
        if pending.any():
            idx = np.flatnonzero(pending)
            self._obs = self.sim.reset(indices=idx, seeds=self.sim.seeds[idx].tolist())
            rewards[pending] = 0.0
            self._pending[:] = False
        truncated = self.sim.dones
        terminated = np.zeros(self.num_envs, dtype=bool)
        infos = self._infos()
        if truncated.any() and self.autoreset_mode == AutoresetMode.NEXT_STEP:
            # the last observation goes out now; the rows are reset (so the simulator can step the others)
            # and the next step returns their first observation
            idx = np.flatnonzero(truncated)
            final = self._copy_obs()
            seeds = [int(self._seed_rngs[i].integers(0, _SEED_HIGH)) for i in idx]
            self._obs = self.sim.reset(indices=idx, seeds=seeds)
            self._reset_fixed()
            self._pending[idx] = True
            return final, rewards.astype(np.float64, copy=False), terminated, truncated, infos
        if truncated.any():
            idx = np.flatnonzero(truncated)
            final = self._copy_obs()
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_info = np.full(self.num_envs, None, dtype=object)
            for i in idx:
                final_obs[i] = final[i] if self.observation_kind == "box" else {k: v[i] for k, v in final.items()}
                final_info[i] = {"t": int(infos["t"][i]), "seed": int(infos["seed"][i])}
            seeds = [int(self._seed_rngs[i].integers(0, _SEED_HIGH)) for i in idx]
            self._obs = self.sim.reset(indices=idx, seeds=seeds)
            self._reset_fixed()
            infos = self._infos()
            infos.update(final_obs=final_obs, _final_obs=truncated.copy(), final_info=final_info,
                         _final_info=truncated.copy())
        return self._copy_obs(), rewards.astype(np.float64, copy=False), terminated, truncated, infos

    # -- masks -------------------------------------------------------------------------------
    def action_masks(self) -> np.ndarray:
        """(B, sum(nvec)) bool: the flat MultiDiscrete masks of every environment (MaskablePPO's convention)."""
        assert self._obs is not None, "call reset() first"
        B = self.num_envs
        parts = [self._obs["dispatch_mask"].reshape(B, -1).astype(bool)]
        if self.kind == "workforce":
            parts += [self._obs["workforce_mask"].astype(bool), np.ones((B, 2 * self.M * POSITIONING_LEVELS), bool)]
        return np.concatenate(parts, axis=1)

    def close_extras(self, **kwargs: Any) -> None:
        self.sim = None



def workforce_vector_env(num_envs: int = 8, **kwargs: Any) -> WorkforceVectorEnv:
    """The vector entry point of ``wfbench/Workforce-v0`` (``gymnasium.make_vec``)."""
    return WorkforceVectorEnv(num_envs=num_envs, kind="workforce", **kwargs)


def dispatch_vector_env(num_envs: int = 8, **kwargs: Any) -> WorkforceVectorEnv:
    """The vector entry point of ``wfbench/Dispatch-v0`` (``gymnasium.make_vec``)."""
    return WorkforceVectorEnv(num_envs=num_envs, kind="dispatch", **kwargs)
