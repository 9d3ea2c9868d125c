"""The policy protocol, the built-in per-decision policies and the composite.

A policy has ``reset(seeds)`` (one seed per environment of the batch it will see) and
``act(obs) -> {agent: batched action}`` for the agents named in ``decisions``. The
evaluator never asks what kind of policy it holds. A :class:`Composite` takes one
policy per decision (that is how the paper's Table 3 rows are built).

Built-in decisions are compiled kernels (:mod:`policies.kernels`); a composite made
only of them can run a whole episode in compiled code (:mod:`policies.rollout`) with
results identical to stepping it through ``act``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from policies import kernels as K
from wfbench.observe import Obs
from wfbench.rng import key_from_seed
from wfbench.simulator import AGENTS

_DECISION_INDEX = {"dispatch": 0, "workforce": 1, "positioning": 2}


@runtime_checkable
class Policy(Protocol):
    """What the evaluator needs of a policy."""

    decisions: tuple[str, ...]

    def reset(self, seeds: Sequence[int]) -> None: ...

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]: ...


def decision_key(env_seed: int, policy_seed: int, decision: str) -> np.uint64:
    """The random key of one decision of a policy in the environment with ``env_seed``.

    Keyed by the environment's seed, never by its batch position, so a seed decides the
    same alone or inside any batch.
    """
    return key_from_seed(int(env_seed), int(policy_seed), 0xB01 + _DECISION_INDEX[decision])


def as_obs(obs: dict[str, np.ndarray]) -> Obs:
    return Obs(**{name: obs[name] for name in Obs._fields})


def seeds_array(seeds: int | Sequence[int]) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(seeds, dtype=np.int64))
    if arr.ndim != 1 or (arr < 0).any():
        raise ValueError(f"seeds must be integers >= 0, one per environment; got {seeds!r}")
    return arr


def hp_vector(hp: dict[str, float], name: str) -> np.ndarray:
    """The hyper-parameter vector (``policies.kernels.HP_FIELDS`` order) with ``hp`` over the defaults."""
    unknown = set(hp) - set(K.HP_FIELDS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for {name}; allowed: {list(K.HP_FIELDS)}")
    params = dict(K.HP_DEFAULTS, **hp)
    return np.array([float(params[f]) for f in K.HP_FIELDS])


class BuiltinDecision:
    """One decision made by a compiled kernel (see :mod:`policies.kernels` for the codes)."""

    def __init__(self, decision: str, code: int, name: str, seed: int = 0, **hp: float):
        if decision not in _DECISION_INDEX:
            raise ValueError(f"unknown decision {decision!r}; allowed: {AGENTS}")
        self.hp = hp_vector(hp, name)
        self.decisions = (decision,)
        self.decision = decision
        self.code = int(code)
        self.name = name
        self.seed = int(seed)
        self.state: K.PolicyState | None = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"

    def reset(self, seeds: int | Sequence[int]) -> None:
        seeds = seeds_array(seeds)
        self._seeds = seeds
        self.state = None  # allocated at the first act, when M is known

    def _ensure_state(self, obs: Obs) -> K.PolicyState:
        B, M = obs.facilities.shape[:2]
        N = obs.personnel.shape[1]
        if self.state is None or self.state.prev_xy.shape[:2] != (B, N) or self.state.demand.shape != (B, M):
            seeds = getattr(self, "_seeds", None)
            if seeds is None or len(seeds) != B:
                raise RuntimeError(f"{self!r}: call reset(seeds) with {B} seed(s) before act()")
            self.state = K.allocate_state(B, M, N)
            d = _DECISION_INDEX[self.decision]
            for b, s in enumerate(seeds):
                self.state.keys[b, d] = decision_key(s, self.seed, self.decision)
        return self.state

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        o = as_obs(obs)
        S = self._ensure_state(o)
        B, M = o.facilities.shape[:2]
        N = o.personnel.shape[1]
        codes = np.zeros(3, dtype=np.int64)
        codes[_DECISION_INDEX[self.decision]] = self.code
        dispatch = np.full((B, M), N, dtype=np.int64)
        workforce = np.zeros(B, dtype=np.int64)
        positioning = np.zeros((B, 2, M), dtype=np.float64)
        hp = np.zeros((3, len(K.HP_FIELDS)))
        hp[_DECISION_INDEX[self.decision]] = self.hp
        K.act_batch(o, S, codes, hp, dispatch, workforce, positioning, np.asarray(obs["t"], dtype=np.int64))
        made = {"dispatch": dispatch, "workforce": workforce, "positioning": positioning}
        return {self.decision: made[self.decision]}


def _decision_policy(decision: str, spec: Any) -> Any:
    from policies.registry import DECISIONS

    if isinstance(spec, str):
        table = DECISIONS[decision]
        if spec not in table:
            raise ValueError(f"unknown {decision} policy {spec!r}; available: {', '.join(table)}")
        return table[spec]()
    if not hasattr(spec, "act") or decision not in getattr(spec, "decisions", AGENTS):
        raise ValueError(f"{spec!r} cannot make the {decision} decision")
    return spec


class Composite:
    """One policy per decision: ``Composite(dispatch=..., workforce=..., positioning=...)``.

    Each argument is a policy object or the name of a built-in decision policy
    (``policies.registry.DECISIONS``).
    """

    def __init__(self, dispatch: Any, workforce: Any, positioning: Any, name: str | None = None):
        self.parts = {
            "dispatch": _decision_policy("dispatch", dispatch),
            "workforce": _decision_policy("workforce", workforce),
            "positioning": _decision_policy("positioning", positioning),
        }
        self.decisions = AGENTS
        self.name = name or "+".join(getattr(p, "name", type(p).__name__) for p in self.parts.values())

    def __repr__(self) -> str:
        return f"Composite({self.name!r})"

    def reset(self, seeds: int | Sequence[int]) -> None:
        done: set[int] = set()
        for p in self.parts.values():
            if id(p) not in done:
                p.reset(seeds)
                done.add(id(p))

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        cache: dict[int, dict[str, np.ndarray]] = {}
        for decision, p in self.parts.items():
            if id(p) not in cache:
                cache[id(p)] = p.act(obs)
            out[decision] = cache[id(p)][decision]
        return out

    @property
    def compiled(self) -> bool:
        """True when every part is a built-in kernel, so a whole episode can run compiled."""
        return all(isinstance(p, BuiltinDecision) for p in self.parts.values())

    def compiled_plan(self, seeds: Sequence[int], M: int, N: int) -> tuple[np.ndarray, np.ndarray, K.PolicyState]:
        """Codes, hyper-parameters and fresh state for :func:`policies.rollout.rollout`."""
        if not self.compiled:
            raise ValueError(f"{self!r} has parts that are not built-in kernels")
        seeds = seeds_array(seeds)
        B = len(seeds)
        codes = np.array([self.parts[d].code for d in AGENTS], dtype=np.int64)
        hp = np.stack([self.parts[d].hp for d in AGENTS])
        state = K.allocate_state(B, M, N)
        for d, decision in enumerate(AGENTS):
            part = self.parts[decision]
            for b, s in enumerate(seeds):
                state.keys[b, d] = decision_key(s, part.seed, decision)
        return codes, hp, state
