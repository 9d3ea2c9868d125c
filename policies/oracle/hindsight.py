"""The hindsight rollout, ``oracle-rollout``: the deployable rollout with the true future as its one sample.

:class:`HindsightRollout` decides like :class:`wfbench.policies.lookahead.rollout.Rollout`: the
compiled base acts, and where the base hires or lets go, and every ``R`` steps, each allowed
workforce action (the base's first, so it wins ties) is scored by the NSW of ``H`` steps with the
base playing the later steps. Its one future is the episode's own: a copy of the real state,
trace included (a shadow ``Simulator(config, seeds)`` stepped with its own actions), rolled
forward by :func:`wfbench.policies.kernels.forward.roll_forward`. With ``H`` to the end of the
episode a score is the exact rest of the episode, so the policy is one step of exact policy
improvement over its base, and scores at least the base on every seed. It reads the trace: not
deployable (``docs/hindsight.md``, "The hindsight rollout").

On a world as large as ``city`` (``large``, which the registry's ``oracle-rollout`` sets to what
the deployable rollout's city preset plays: more facility-person pairs than
:data:`~wfbench.policies.lookahead.rollout.AUTO_SPARSE_PAIRS`, the base's sparse twin deciding
every ``R`` steps only, its futures played by the twin's spatial twin): there the dense base
costs 0.6-1 s a step, and 7 futures of the rest of the episode at every hire would cost hours a
seed. Its scores are then those of the cheaper futures, so the improvement is not exact there.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.kernels.forward import RollBuffers, roll_candidates
from wfbench.policies.protocol import Attached, as_obs, seeds_array

from wfbench.core.actions import AGENTS
from wfbench.core.config import ScenarioConfig
from wfbench.core.fork import copy_state, fork
from wfbench.core.simulator import Simulator

N_WORKFORCE = 7  # the workforce actions: no-op, three hires, three let-gos
KNOBS = {"H": "steps of each roll-forward (None: to the end of the episode)",
         "R": "steps between two decisions the base did not ask for"}


def _knob(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise ValueError(f"oracle-rollout knob {name} = {value!r} is not allowed; allowed: an integer >= 1 "
                         f"({KNOBS[name]})")
    return int(value)


class HindsightRollout(Attached):
    """Rollout of the compiled composite ``base`` on the episode's true future (module docstring).

    Args:
        base: a composite of built-in kernels (``Composite.compiled``), e.g. ``policies.get("solver-tuned")``.
        H: steps of each roll-forward; None (the default) rolls to the end of the episode.
        R: steps between two decisions the base did not ask for (the 10 ms rollout's 20).
        name: its name in tables.
        large: (pairs, base, futures): on a world of more than ``pairs`` facility-person slot pairs,
            that compiled base decides every R steps only and those compiled futures play the
            roll-forwards (module docstring); None (the default): ``base`` on every world.
    """

    reads_trace = True
    decisions = AGENTS

    def __init__(self, base: Any, H: int | None = None, R: int = 20, name: str = "oracle-rollout",
                 large: tuple[int, Any, Any] | None = None):
        for b in (base, *(large[1:] if large is not None else ())):
            if not getattr(b, "compiled", False):
                raise ValueError(f"oracle-rollout base {getattr(b, 'name', b)!r} is not a composite of built-in "
                                 "kernels; allowed: a compiled composite (a registry composite or tuned file of one)")
        self.large = large
        self._dense = base
        self.base = base
        self.H = None if H is None else _knob("H", H)
        self.R = _knob("R", R)
        self.name = name
        self.config: ScenarioConfig | None = None
        self.shadow: Simulator | None = None
        self.last_scores: np.ndarray | None = None  # (B, 7) the score of each workforce action at the last decision
        self.timing: dict[str, float] = {}

    def __repr__(self) -> str:
        return f"HindsightRollout({getattr(self.base, 'name', self.base)!r}, H={self.H}, R={self.R})"

    def settings(self) -> dict[str, Any]:
        out: dict[str, Any] = {"H": self.H, "R": self.R}
        if self.large is not None:
            out["large"] = f"> {self.large[0]:,} pairs: {self.large[1].name}, futures {self.large[2].name}"
        return out

    def reset(self, seeds: int | Sequence[int]) -> None:
        """Start the shadow of the coming batch (``attach`` first)."""
        self._attached()
        self._seeds = seeds_array(seeds)
        self.shadow = Simulator(self.config, [int(s) for s in self._seeds], keep_series=False, threads=1)
        self.shadow.reset()
        B, M, N = self.shadow.B, self.shadow.M, self.shadow.N
        self.B, self.M, self.N = B, M, N
        large = self.large is not None and M * N > self.large[0]
        self.base = self.large[1] if large else self._dense
        self.codes, self.hp, self.pstate = self.base.compiled_plan(self._seeds, M, N)
        # the futures' kernels: the base's, or on a large world those of its futures (the state is the base's)
        self.f_codes, self.f_hp = (self.large[2].compiled_plan(self._seeds, M, N)[:2] if large
                                   else (self.codes, self.hp))
        self.period = large  # decide every R steps only
        self.fork = fork(self.shadow, copies=N_WORKFORCE, keep_series=False, threads=1)
        self.fork_pstate = K.allocate_state(self.fork.B, M, N)
        self.buffers = RollBuffers(self.fork.B, M, N, onset_capacity=1)
        self.steps = self.config.horizon if self.H is None else self.H
        self.timing = {"steps": 0.0, "act_s": 0.0, "decisions": 0.0, "rolls": 0.0}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if self.shadow is None:
            raise RuntimeError("call attach(config) and reset(seeds) before act()")
        start = time.perf_counter()
        t = np.asarray(obs["t"], dtype=np.int64)
        if t.shape[0] != self.B or not np.array_equal(t, self.shadow.state.t):
            raise RuntimeError(f"{self.name}: the observation is not of the episode it was reset for (step "
                               f"{t.tolist()[:3]}, its shadow at {self.shadow.state.t.tolist()[:3]}): reset it")
        B, M, N = self.B, self.M, self.N
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        K.act_batch(as_obs(obs), self.pstate, self.codes, self.hp, d, w, p, t)
        decide = np.flatnonzero((t % self.R == 0) if self.period else (w != 0) | (t % self.R == 0))
        self.last_scores = None
        if decide.size:
            self._decide(decide, np.asarray(obs["workforce_mask"]), d, w, p)
        actions = {"dispatch": d, "workforce": w, "positioning": p}
        self.shadow.step(actions)  # the real episode takes exactly these: the shadow stays its copy
        self.timing["steps"] += 1
        self.timing["act_s"] += time.perf_counter() - start
        return actions

    def _decide(self, envs: np.ndarray, mask: np.ndarray, d: np.ndarray, w: np.ndarray, p: np.ndarray) -> None:
        """Score every allowed workforce action of ``envs`` on the true future; keep the best (the base's on a tie)."""
        cands = {int(b): [int(w[b])] + [a for a in range(N_WORKFORCE) if a != w[b] and mask[b, a]] for b in envs}
        rows_env = np.array([b for b in cands for _ in cands[b]], dtype=np.int64)
        rows_a = np.array([a for b in cands for a in cands[b]], dtype=np.int64)
        n = rows_env.size
        copy_state(self.fork, self.shadow, rows_env)
        score = roll_candidates(self.fork, self.steps, self.f_codes, self.f_hp, self.pstate, self.fork_pstate,
                                self.buffers, rows_env, rows_a, d, p)
        scores = np.full((self.B, N_WORKFORCE), np.nan)
        i = 0
        for b, allowed in cands.items():
            k = i + int(np.argmax(score[i: i + len(allowed)]))  # the first of the best: the base's on a tie
            scores[b, allowed] = score[i: i + len(allowed)]
            w[b] = rows_a[k]
            i += len(allowed)
        self.timing["decisions"] += len(envs)
        self.timing["rolls"] += n
        self.last_scores = scores


__all__ = ["KNOBS", "HindsightRollout"]
