"""PettingZoo environments: ``parallel_env(...)`` (ParallelEnv) and ``env(...)`` (AEC).

:class:`WorkforceParallelEnv` has the agents ``dispatch``, ``workforce`` and ``positioning``,
acting at every step on the same observation (the shared features and the masks
``dispatch_mask`` and ``workforce_mask``) and sharing the step's NSW as reward.
``fixed={"workforce": "threshold"}`` hands an agent to a built-in policy, and it leaves
``agents``. Options for libraries that want one shape for everything (``observation="box"``,
``actions="shared"``, ``positioning="flat"``, ``info``, ``obs_version``), ``state()`` for a
centralized critic and what each library needs: ``docs/envs.md``.
"""

from __future__ import annotations

import operator
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils import parallel_to_aec, wrappers

from wfbench.core.actions import AGENTS, ActionError, actions_in_range, validate_actions
from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.kpis import KPI_NAMES
from wfbench.core.simulator import Simulator
from wfbench.core.state import COUNTERS, METRICS, N_WORKFORCE_ACTIONS
from wfbench.envs.render import RENDER_MODES, HumanWindow, Rendering, check_render_mode
from wfbench.envs.spaces import (
    INFOS,
    OBSERVATIONS,
    POSITIONINGS,
    check_obs_version,
    check_option,
    dispatch_action_space,
    flat_positioning_action_space,
    joint_nvec,
    observation_space,
    positioning_action_space,
    shared_keys,
    shared_spaces,
    single,
    split_joint,
    unflatten_positioning,
    versioned,
    workforce_action_space,
)
from wfbench.policies import DECISIONS, get
from wfbench.policies.registry import names
from wfbench.policies.tuned import is_tuned_spec
from wfbench.scenarios.resolve import resolve_scenario

_INFO_METRICS = tuple((k, METRICS.index(k)) for k in KPI_NAMES)
_FLAT_METRICS = tuple(f"metric_{k}" for k in KPI_NAMES)
_FLAT_COUNTS = tuple(f"count_{k}" for k in COUNTERS)
_FLAT_STEP_COUNTS = tuple(f"step_count_{k}" for k in COUNTERS)
ACTIONS = ("own", "shared")  # the PettingZoo environment's ``actions=`` option


def resolve_fixed(fixed: dict[str, Any] | None) -> dict[str, Any]:
    """Policies for the fixed agents; names are decision policies or composites."""
    out: dict[str, Any] = {}
    for agent, spec in (fixed or {}).items():
        if agent not in AGENTS:
            raise ValueError(f"fixed names unknown agent {agent!r}; agents: {', '.join(AGENTS)}")
        if isinstance(spec, str) and spec in DECISIONS[agent]:
            out[agent] = DECISIONS[agent][spec]()
        elif isinstance(spec, str) and spec not in names() and ":" not in spec and not is_tuned_spec(spec):
            allowed = ", ".join([*DECISIONS[agent], *names()])
            raise ValueError(f"unknown policy {spec!r} for fixed agent {agent!r}; available: {allowed}")
        else:
            out[agent] = get(spec)
    return out


class WorkforceCore:
    """What the PettingZoo and Gymnasium environments share: one simulator with B = 1.

    The step is on the path of every environment step, so its Python work is kept small:
    actions of the expected kinds (integer dispatch and workforce, float positioning) are
    copied into preallocated plain buffers and checked by one compiled range test; any
    other form, and every malformed action, goes through
    :func:`wfbench.core.actions.validate_actions`, which converts it or names the bad index.
    """

    def __init__(self, scenario: ScenarioConfig, fixed: dict[str, Any] | None):
        self.config = require_config(scenario, "WorkforceCore")
        self.fixed = resolve_fixed(fixed)
        self.sim: Simulator | None = None
        self.obs: dict[str, np.ndarray] | None = None
        self.seed: int | None = None
        self._seed_rng = np.random.default_rng()
        self.last_counters: dict[str, int] = {}
        M = self.config.max_facilities
        # one batched (B = 1) buffer per agent, with the integer kinds ("iu") or float kind ("f") copied as is
        self._buffers = (("dispatch", np.zeros((1, M), dtype=np.int64), "iu"),
                         ("workforce", np.zeros(1, dtype=np.int64), "iu"),
                         ("positioning", np.zeros((1, 2, M)), "f"))
        self._free = frozenset(a for a in AGENTS if a not in self.fixed)

    def reset(self, seed: int | None) -> dict[str, np.ndarray]:
        """Start an episode; ``seed=None`` continues the seed sequence of the last seeded reset."""
        if seed is not None:
            self._seed_rng = np.random.default_rng(seed)
            self.seed = int(seed)
        else:
            self.seed = int(self._seed_rng.integers(0, 2**31 - 1))
        self.sim = Simulator(self.config, [self.seed])
        self.obs = self.sim.reset()
        self.last_counters = dict.fromkeys(COUNTERS, 0)
        self._counts: list[int] = self.sim.state.counters[0].tolist()  # the counters, as of the last reset or step
        for p in {id(p): p for p in self.fixed.values()}.values():
            p.reset([self.seed])
        return self.obs

    def _fixed_actions(self) -> dict[str, np.ndarray]:
        """The fixed agents' batched actions on the current observation (each policy acts once)."""
        assert self.obs is not None
        out: dict[str, np.ndarray] = {}
        cache: dict[int, dict[str, np.ndarray]] = {}
        for agent, p in self.fixed.items():
            if id(p) not in cache:
                cache[id(p)] = p.act(self.obs)
            out[agent] = cache[id(p)][agent]
        return out

    def full_action(self, given: dict[str, Any], fixed: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Batched (B = 1) actions of all agents: the given ones plus the fixed agents' choices."""
        out = dict(self._fixed_actions() if fixed is None else fixed)
        for agent, a in given.items():
            if agent in self.fixed:
                raise ActionError(f"agent {agent!r} is fixed to {self.fixed[agent]!r}; do not pass its action")
            out[agent] = np.asarray(a)[None]
        return out

    def actions(self, given: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The checked batched actions (dispatch, workforce, positioning) of all agents for this step."""
        assert self.sim is not None
        fixed = self._fixed_actions() if self.fixed else {}
        plain = given.keys() == self._free
        for agent, buf, kinds in self._buffers:
            if not plain:
                break
            if agent in fixed:
                a, shape, where = fixed[agent], buf.shape, ...
            else:
                a, shape, where = np.asarray(given[agent]), buf.shape[1:], 0
            plain = type(a) is np.ndarray and a.dtype.kind in kinds and a.shape == shape
            if plain:
                buf[where] = a
        d, w, p = (buf for _, buf, _ in self._buffers)
        if plain and self.sim.call(actions_in_range, d, w, p, self.sim.N, N_WORKFORCE_ACTIONS - 1):
            return d, w, p
        return validate_actions(self.full_action(given, fixed), 1, self.sim.M, self.sim.N)

    def step(self, given: dict[str, Any]) -> tuple[float, dict[str, int]]:
        assert self.sim is not None
        self.sim.check_ready()  # before the fixed policies act: a refused step changes nothing
        counters = self.sim.state.counters[0]
        before = counters.tolist()
        rewards, self.obs = self.sim.step_observe_checked(*self.actions(given))
        self._counts = counters.tolist()
        self.last_counters = dict(zip(COUNTERS, map(operator.sub, self._counts, before), strict=True))
        return float(rewards[0]), self.last_counters

    def info(self, kind: str = "nested") -> dict[str, Any]:
        """The step's info: ``kind="nested"`` tallies in dicts, ``"flat"`` numbers under one level of keys."""
        assert self.sim is not None
        state = self.sim.state
        last = state.last[0].tolist()
        if kind == "flat":
            out: dict[str, Any] = {"t": int(state.t[0]), "seed": self.seed}
            out.update(zip(_FLAT_METRICS, [last[i] for _, i in _INFO_METRICS], strict=True))
            out.update(zip(_FLAT_COUNTS, self._counts, strict=True))
            out.update(zip(_FLAT_STEP_COUNTS, self.last_counters.values(), strict=True))
            return out
        return {
            "t": int(state.t[0]), "seed": self.seed, "step_counts": dict(self.last_counters),
            "counts": dict(zip(COUNTERS, self._counts, strict=True)),
            "metrics": {k: last[i] for k, i in _INFO_METRICS},
        }


class WorkforceParallelEnv(Rendering, ParallelEnv):
    """The three-agent workforce environment (PettingZoo Parallel API)."""

    metadata = {"name": "wfbench_workforce_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True,
                "render_fps": 8}

    def __init__(self, scenario: str | ScenarioConfig = "paper-64", fixed: dict[str, Any] | None = None,
                 render_mode: str | None = None, observation: str = "dict", actions: str = "own",
                 info: str = "flat", obs_version: int = 1, positioning: str = "2d"):
        check_render_mode(render_mode)
        self.obs_version = check_obs_version(obs_version)
        if self.obs_version == 2:
            self.metadata = {**type(self).metadata, "name": "wfbench_workforce_v1"}
        self.observation_kind = check_option("observation", observation, OBSERVATIONS)
        self.actions_kind = check_option("actions", actions, ACTIONS)
        self.info_kind = check_option("info", info, INFOS)
        self.positioning_kind = check_option("positioning", positioning, POSITIONINGS)
        if positioning == "flat" and actions == "shared":
            raise ValueError("positioning='flat' is not allowed with actions='shared', whose positioning is already "
                             "flat (2M levels of the shared MultiDiscrete); allowed: positioning='flat' with "
                             "actions='own'")
        self.core = WorkforceCore(resolve_scenario(scenario), fixed)  # a name enters here (parallel_env, env)
        self.config = self.core.config
        self.render_mode = render_mode
        self.possible_agents = [a for a in AGENTS if a not in self.core.fixed]
        if not self.possible_agents:
            raise ValueError("every agent is fixed; leave at least one of dispatch, workforce, positioning free")
        self.agents: list[str] = []
        M, N = self.config.max_facilities, self.config.max_personnel
        shared = shared_spaces(self.config, self.obs_version)
        self._shared_keys = shared_keys(self.obs_version)
        self._obs_keys = (*self._shared_keys, "dispatch_mask", "workforce_mask")
        self._dict_space = spaces.Dict({
            **shared,
            "dispatch_mask": spaces.Box(0, 1, shape=(M, N + 1), dtype=np.int8),
            "workforce_mask": spaces.Box(0, 1, shape=(7,), dtype=np.int8),
        })
        self._obs_space = observation_space(self._dict_space, observation)
        self._state_dict_space = spaces.Dict({k: shared[k] for k in self._shared_keys})
        self.state_space = spaces.flatten_space(self._state_dict_space)
        if actions == "shared":
            joint = spaces.MultiDiscrete(joint_nvec(self.config))
            self._act_spaces = dict.fromkeys(AGENTS, joint)
        else:
            flat = positioning == "flat"
            self._act_spaces = {
                "dispatch": dispatch_action_space(self.config),
                "workforce": workforce_action_space(),
                "positioning": (flat_positioning_action_space if flat else positioning_action_space)(self.config),
            }
        # ParallelEnv's declared dicts (skrl's multi-agent wrapper reads them), one space object per agent
        self.observation_spaces = dict.fromkeys(self.possible_agents, self._obs_space)
        self.action_spaces = {a: self._act_spaces[a] for a in self.possible_agents}
        self._window: HumanWindow | None = None

    def observation_space(self, agent: str) -> spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self.action_spaces[agent]

    def _observations(self) -> dict[str, dict[str, np.ndarray]]:
        # Copies, because the simulator's buffers are overwritten by the next step. The
        # agents see the same observation, so their dicts share one set of copies (a
        # third of the copying); an agent's arrays are never written by the environment.
        shared = single(versioned(self.core.obs, self.obs_version), self._obs_keys)
        if self.observation_kind == "box":
            flat = spaces.flatten(self._dict_space, shared)
            return dict.fromkeys(self.agents, flat)
        return {a: dict(shared) for a in self.agents}

    def reset(self, seed: int | None = None, options: dict | None = None):
        self.core.reset(seed)
        self.agents = list(self.possible_agents)
        info = self.core.info(self.info_kind)
        obs = self._observations()
        self._show()
        return obs, {a: dict(info) for a in self.agents}

    def step(self, actions: dict[str, Any]):
        if not self.agents:
            raise RuntimeError("the episode is over; call reset()")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ActionError(f"missing action for agent(s) {missing}; agents: {self.agents}")
        if self.actions_kind == "shared":
            given = {}
            for a in self.agents:
                joint = np.asarray(actions[a])
                if joint.shape != self._act_spaces[a].shape:
                    raise ActionError(f"action of agent {a!r} has shape {joint.shape}; "
                                      f"allowed: {self._act_spaces[a].shape}, the shared MultiDiscrete")
                given[a] = split_joint(joint, self.config.max_facilities)[a]
        else:
            given = {a: actions[a] for a in self.agents}
            if self.positioning_kind == "flat" and "positioning" in given:
                given["positioning"] = unflatten_positioning(given["positioning"], self.config.max_facilities)
        reward, _ = self.core.step(given)
        info = self.core.info(self.info_kind)
        truncated = self.core.sim.done  # type: ignore[union-attr]
        agents = list(self.agents)
        obs = self._observations()
        if truncated:
            self.agents = []
        self._show()
        return (obs, {a: reward for a in agents}, {a: False for a in agents}, {a: truncated for a in agents},
                {a: dict(info) for a in agents})

    def state(self) -> np.ndarray:
        """A flat global state (the shared observation without masks) for centralized critics, in ``state_space``."""
        obs = self.core.obs
        assert obs is not None
        obs = versioned(obs, self.obs_version)
        return spaces.flatten(self._state_dict_space, {k: obs[k][0] for k in self._shared_keys})


def parallel_env(scenario: str | ScenarioConfig = "paper-64", fixed: dict[str, Any] | None = None,
                 render_mode: str | None = None, observation: str = "dict", actions: str = "own",
                 info: str = "flat", obs_version: int = 1, positioning: str = "2d") -> WorkforceParallelEnv:
    """The PettingZoo Parallel environment (options: the module docstring)."""
    return WorkforceParallelEnv(scenario=scenario, fixed=fixed, render_mode=render_mode, observation=observation,
                                actions=actions, info=info, obs_version=obs_version, positioning=positioning)


def env(scenario: str | ScenarioConfig = "paper-64", fixed: dict[str, Any] | None = None,
        render_mode: str | None = None, observation: str = "dict", actions: str = "own", info: str = "flat",
        obs_version: int = 1, positioning: str = "2d"):
    """The PettingZoo AEC environment (agents act in turn; the step is applied after the last)."""
    aec = parallel_to_aec(parallel_env(scenario=scenario, fixed=fixed, render_mode=render_mode,
                                       observation=observation, actions=actions, info=info,
                                       obs_version=obs_version, positioning=positioning))
    return wrappers.OrderEnforcingWrapper(aec)
