"""Rollout of a compiled base policy on sampled futures: a deployable direct lookahead (issue #43).

At a workforce decision, :class:`Rollout` scores the base's own workforce action and its allowed
neighbours by the mean over ``K`` worlds sampled from what it observed
(:class:`wfbench.core.belief.Belief`) of the NSW summed over ``H`` steps, the base playing every
later step (:func:`wfbench.policies.oracle.rollout.roll_forward`); every candidate meets the same
worlds, and the base's choice wins ties. It decides where the base hires or lets go and every
``R`` steps otherwise. It reads no trace or seed: its public model comes from
:meth:`Rollout.set_world`, ``scenario=`` or the first observation. ``docs/policies.md``,
"Lookahead policies" and "The world's public parameters: set_world".
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.oracle.rollout import RollBuffers, roll_forward
from wfbench.policies.protocol import as_obs, seeds_array

from wfbench.core.actions import AGENTS
from wfbench.core.belief import Belief, config_from_observation
from wfbench.core.config import ScenarioConfig, require_config

# budget presets: (K, H, R), named by the decision time they aim at per env-step on paper-64 (one core);
# docs/policies.md ("Lookahead policies") has the measured cost of each
BUDGETS: dict[str, tuple[int, int, int]] = {
    "1ms": (2, 80, 80),
    "10ms": (4, 80, 20),
    "100ms": (16, 120, 10),
}
DEFAULT_BUDGET = "10ms"
KNOBS = {"K": "sampled futures per candidate", "H": "steps of each roll-forward",
         "R": "steps between two decisions the base did not ask for"}


def knob(name: str, value: Any) -> int:
    """``value`` as a knob's integer >= 1; ValueError of one line naming the knob otherwise."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if ok and isinstance(value, (float, np.floating)):
        ok = math.isfinite(value) and float(value).is_integer()
    if not ok or int(value) < 1:
        raise ValueError(f"rollout knob {name} = {value!r} is not allowed; allowed: an integer >= 1 "
                         f"({KNOBS[name]})")
    return int(value)


def budget(name: str) -> tuple[int, int, int]:
    """The (K, H, R) of a budget preset; ValueError of one line naming the presets otherwise."""
    if name not in BUDGETS:
        raise ValueError(f"rollout budget {name!r} is not allowed; allowed: {', '.join(BUDGETS)}")
    return BUDGETS[name]


class RolloutBase:
    """What every rollout shares: its knobs from a budget preset, its base, name and seed, the public world.

    The subclasses (:class:`Rollout`, and
    :class:`~wfbench.policies.lookahead.network_rollout.NetworkRollout`) check their base and
    call this after.
    """

    decisions = AGENTS
    reads_trace = False

    def __init__(self, base: Any, K: int | None, H: int | None, R: int | None, budget: str,
                 scenario: ScenarioConfig | None, seed: int, name: str):
        k0, h0, r0 = globals()["budget"](budget)
        self.K = knob("K", k0 if K is None else K)
        self.H = knob("H", h0 if H is None else H)
        self.R = knob("R", r0 if R is None else R)
        self.base = base
        self.seed = int(seed)
        self.name = name
        self.config = None if scenario is None else require_config(scenario, f"{name} scenario=")
        self.belief: Belief | None = None
        self.last_scores: np.ndarray | None = None  # (B, 7) mean score per workforce action at the last decision
        self.timing: dict[str, float] = {}

    def settings(self) -> dict[str, int]:
        return {"K": self.K, "H": self.H, "R": self.R}

    def set_world(self, config: ScenarioConfig) -> None:
        """The public config of the world (optional: without it the model comes from the first observation).

        The evaluator calls it before ``reset`` with the scenario's public parameters
        (:func:`wfbench.harness.runner.public_world`); it replaces ``scenario=``.
        """
        self.config = require_config(config, f"{self.name}.set_world")


class Rollout(RolloutBase):
    """Rollout of the compiled composite ``base`` on K sampled futures of H steps (module docstring).

    Args:
        base: a composite of built-in kernels (``Composite.compiled``), e.g. ``policies.get("solver-tuned")``.
        K, H, R: the knobs (:data:`KNOBS`), integers >= 1; None takes the ``budget`` preset's.
        budget: a preset of :data:`BUDGETS` for the knobs not given.
        scenario: the public config of the world (a :class:`ScenarioConfig`); None: from
            :meth:`set_world` (the evaluator's), else built from the first observation.
        seed: the policy's own seed, mixed into its belief keys.
        name: the policy's name.
    """

    def __init__(self, base: Any, K: int | None = None, H: int | None = None, R: int | None = None,
                 budget: str = DEFAULT_BUDGET, scenario: ScenarioConfig | None = None, seed: int = 0,
                 name: str | None = None):
        if not getattr(base, "compiled", False):
            raise ValueError(f"rollout base {getattr(base, 'name', base)!r} is not a composite of built-in kernels; "
                             "allowed: a compiled composite (a registry composite or tuned file of one)")
        name = name or f"rollout-{getattr(base, 'name', 'base')}"
        super().__init__(base, K, H, R, budget, scenario, seed, name)

    # the name of before; the runner hands ``attach`` only to policies that read the trace
    attach = RolloutBase.set_world

    def reset(self, seeds: int | Sequence[int]) -> None:
        self._seeds = seeds_array(seeds)
        self.belief = None  # made at the first observation (its M and N, and the model if none was given)

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        config = self.config or config_from_observation(obs)
        B, M, N = obs["facilities"].shape[0], obs["facilities"].shape[1], obs["personnel"].shape[1]
        if len(self._seeds) != B:
            raise RuntimeError(f"{self.name}: reset with {len(self._seeds)} seed(s), observed {B} environment(s)")
        self.belief = Belief(config)
        self.belief.reset(self._seeds, self.seed)
        codes, hp, pstate = self.base.compiled_plan(self._seeds, M, N)
        self.codes, self.hp, self.pstate = codes, hp, pstate
        rows = B * 7 * self.K
        self.fork = self.belief.simulator(rows)
        self.fork_pstate = K.allocate_state(rows, M, N)
        self.buffers = RollBuffers(rows, M, N, onset_capacity=1)
        self.B, self.M, self.N = B, M, N
        self.timing = {"steps": 0.0, "act_s": 0.0, "decisions": 0.0, "rolls": 0.0}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        start = time.perf_counter()
        if self.belief is None or int(np.asarray(obs["t"]).reshape(-1)[0]) == 0 and self.belief.t[0] > 0:
            self._start(obs)
        self.belief.update(obs)
        B, M, N = self.B, self.M, self.N
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        t = np.asarray(obs["t"], dtype=np.int64)
        K.act_batch(as_obs(obs), self.pstate, self.codes, self.hp, d, w, p, t)
        decide = (w != 0) | (t % self.R == 0)
        self.last_scores = None
        if decide.any():
            self._decide(obs, np.flatnonzero(decide), d, w, p)
        self.timing["steps"] += 1
        self.timing["act_s"] += time.perf_counter() - start
        return {"dispatch": d, "workforce": w, "positioning": p}

    def _decide(self, obs, envs: np.ndarray, d, w, p) -> None:
        """Score every allowed workforce action of ``envs`` on K common sampled futures; keep the best."""
        cands, rows_env, rows_a, rows_k = candidate_rows(envs, w, obs["workforce_mask"], self.K)
        n = len(rows_env)
        env_idx = np.asarray(rows_env, dtype=np.int64)
        self.belief.sample_into(self.fork, env_idx, np.asarray(rows_k, dtype=np.int64), self.H)
        for src, dst in zip(self.pstate, self.fork_pstate, strict=True):
            np.take(src, env_idx, axis=0, out=dst[:n])
        buf = self.buffers
        buf.first_d[:n] = d[env_idx]
        buf.first_w[:n] = rows_a
        buf.first_p[:n] = p[env_idx]
        score = roll_forward(self.fork, self.H, self.codes, self.hp, self.fork_pstate, first=True, buffers=buf,
                             rows=n)[:n]
        self.timing["decisions"] += len(envs)
        self.timing["rolls"] += n
        self.last_scores = pick_best(score, envs, cands, self.K, w, self.B)


def candidate_rows(envs: np.ndarray, w: np.ndarray, mask: np.ndarray,
                   K: int) -> tuple[dict[int, list[int]], list[int], list[int], list[int]]:
    """The candidates of each deciding environment and the fork rows that score them.

    Each environment's candidates are the base's workforce action ``w[b]`` first, then every
    other action its mask allows; each candidate gets K rows, sample k = 0..K-1 (the same K
    worlds for every candidate). Returns the candidates per environment and, per row, its
    environment, action and sample.
    """
    rows_env, rows_a, rows_k = [], [], []
    cands: dict[int, list[int]] = {}
    for b in envs:
        allowed = [int(w[b])] + [a for a in range(7) if a != w[b] and mask[b, a]]
        cands[int(b)] = allowed
        for a in allowed:
            for k in range(K):
                rows_env.append(int(b))
                rows_a.append(a)
                rows_k.append(k)
    return cands, rows_env, rows_a, rows_k


def pick_best(score: np.ndarray, envs: np.ndarray, cands: dict[int, list[int]], K: int, w: np.ndarray,
              B: int) -> np.ndarray:
    """Set ``w[b]`` to each environment's best candidate by its mean over its K rows; the (B, 7) mean scores.

    The rows of ``score`` are in :func:`candidate_rows`' order. The base's action is first,
    so it wins ties.
    """
    scores = np.full((B, 7), np.nan)
    i = 0
    for b in envs:
        best_a, best_v = None, -np.inf
        for a in cands[int(b)]:
            v = float(score[i: i + K].mean())
            scores[b, a] = v
            if v > best_v:
                best_a, best_v = a, v
            i += K
        w[b] = best_a
    return scores


def make(base: Any, budget_name: str = DEFAULT_BUDGET, name: str | None = None, **knobs: Any) -> Rollout:
    """A :class:`Rollout` of ``base`` at a budget preset, knobs overriding it."""
    return Rollout(base, budget=budget_name, name=name, **knobs)


__all__ = ["BUDGETS", "DEFAULT_BUDGET", "KNOBS", "Rollout", "RolloutBase", "budget", "candidate_rows", "knob", "make",
           "pick_best"]
