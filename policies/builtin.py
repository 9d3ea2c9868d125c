"""Built-in decisions: one decision made by a compiled kernel of :mod:`wfbench.policies.kernels`.

Which rules there are, their codes and what a tuner may change are the rows of
:data:`wfbench.policies.rules.RULES`.

A :class:`BuiltinDecision` is a policy for one agent; a composite made only of them can
run a whole episode in compiled code (:mod:`wfbench.policies.episode`) with results identical to
stepping it through ``act``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.protocol import DECISION_INDEX, as_obs, decision_key, hp_vector, seeds_array
from wfbench.policies.rules import RULES
from wfbench.policies.tunable import Param

from wfbench.core.actions import AGENTS
from wfbench.core.observe import Obs


class BuiltinDecision:
    """One decision made by a compiled kernel: ``code`` is a rule's (:data:`wfbench.policies.rules.RULES`)."""

    def __init__(self, decision: str, code: int, name: str, seed: int = 0, **hp: float):
        if decision not in DECISION_INDEX:
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

    @property
    def tunable(self) -> dict[str, Param]:
        """The hyper-parameters a tuner may change, with their ranges (the rule's row of ``RULES``)."""
        rule = next((r for r in RULES if r.decision == self.decision and r.code == self.code), None)
        return rule.params if rule is not None else {}

    def params(self) -> dict[str, float]:
        """The current value of each tunable hyper-parameter."""
        return {f: float(self.hp[K.HP_FIELDS.index(f)]) for f in self.tunable}

    def with_params(self, name: str | None = None, **values: float) -> BuiltinDecision:
        """A copy with some tunable hyper-parameters changed; ValueError names a bad name or value."""
        allowed = self.tunable
        for f, v in values.items():
            if f not in allowed:
                raise ValueError(f"{self.name} has no tunable parameter {f!r}; allowed: "
                                 f"{', '.join(allowed) or 'none'}")
            allowed[f].check(v, f)
        hp = {f: float(self.hp[i]) for i, f in enumerate(K.HP_FIELDS)}
        hp.update({f: float(v) for f, v in values.items()})
        return BuiltinDecision(self.decision, self.code, name or self.name, seed=self.seed, **hp)

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
            d = DECISION_INDEX[self.decision]
            for b, s in enumerate(seeds):
                self.state.keys[b, d] = decision_key(s, self.seed, self.decision)
        return self.state

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        o = as_obs(obs)
        S = self._ensure_state(o)
        B, M = o.facilities.shape[:2]
        N = o.personnel.shape[1]
        codes = np.zeros(3, dtype=np.int64)
        codes[DECISION_INDEX[self.decision]] = self.code
        dispatch = np.full((B, M), N, dtype=np.int64)
        workforce = np.zeros(B, dtype=np.int64)
        positioning = np.zeros((B, 2, M), dtype=np.float64)
        hp = np.zeros((3, len(K.HP_FIELDS)))
        hp[DECISION_INDEX[self.decision]] = self.hp
        K.act_batch(o, S, codes, hp, dispatch, workforce, positioning, np.asarray(obs["t"], dtype=np.int64))
        made = {"dispatch": dispatch, "workforce": workforce, "positioning": positioning}
        return {self.decision: made[self.decision]}
