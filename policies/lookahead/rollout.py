"""Rollout of a compiled base policy on sampled futures: a deployable direct lookahead (issue #43).

At a workforce decision, :class:`Rollout` scores the base's action and its allowed neighbours by
the mean NSW over ``H`` steps of ``K`` worlds sampled from what it observed (:class:`wfbench.core.belief.Belief`),
the base playing the later steps (:func:`wfbench.policies.kernels.forward.roll_forward`); common worlds,
ties to the base. It decides where the base hires or lets go and every ``R`` steps. The ``sparse:``
presets, for ``city``: the base's :func:`sparse_twin`, a decision every R steps only, futures with
spatial positioning (:func:`spatial_twin`); ``sparse="auto"`` plays them only on a world as large as
``city`` (:func:`plays_sparse`). It reads no trace or seed: its model comes from
:meth:`Rollout.set_world`, ``scenario=`` or the first observation. ``docs/policies.md``, "Lookahead policies".
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.composite import Composite
from wfbench.policies.kernels.forward import RollBuffers, roll_candidates
from wfbench.policies.lookahead.knobs import whole
from wfbench.policies.protocol import as_obs, seeds_array
from wfbench.policies.rules import CODES

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
# the dense solver rules and their twins on sparse candidate graphs, the k nearest (docs/solvers.md, "Sparse
# candidate graphs"): the same hyper-parameters, the same kernels in the roll-forward (policies/kernels/act.py)
SPARSE_TWINS: dict[str, str] = {"assignment": "assignment-sparse", "facility-location": "facility-location-sparse"}
DECIDE = {"base": "where the base hires or lets go, and every R steps", "period": "every R steps only"}
# a budget "sparse:PRESET": PRESET's knobs with sparse=True, decide="period" and the futures played by the sparse twin's
# spatial twin, so that a decision's cost on city does not grow with the p-median solves or with how often the base
# hires (docs/policies.md, "Lookahead policies on city")
SPARSE_PRESET = "sparse:"
# sparse="auto" (the registry's rollout-solver-tuned presets, issue #53): the dense base on a world of at most this
# many (facility slot, person slot) pairs, the sparse preset above it. Every suite-v1 world but city has at most
# 200 x 200 = 40,000 pairs, where the dense assignment costs milliseconds; city has 1,000 x 1,000, where it costs
# 0.6-1 s a step. The world's size is public, so the choice reads nothing a deployable policy may not.
AUTO_SPARSE_PAIRS = 250_000


def knob(name: str, value: Any) -> int:
    """``value`` as a knob's integer >= 1; ValueError of one line naming the knob otherwise."""
    return whole("rollout", name, value, KNOBS[name])


def check_decide(decide: str, allowed: dict[str, str] = DECIDE) -> None:
    """Refuse a ``decide`` knob not in ``allowed`` (value -> what it means) in one line naming them."""
    if decide not in allowed:
        raise ValueError(f"rollout knob decide = {decide!r} is not allowed; allowed: "
                         + ", ".join(f"{k} ({v})" for k, v in allowed.items()))


def sparse_twin(base: Any) -> Composite:
    """The compiled composite ``base`` with its assignment and p-median on sparse candidate graphs, all else kept.

    Each part of :data:`SPARSE_TWINS` becomes its twin with the same hyper-parameters and seed
    (tuned values stay tuned); a part already sparse stays. Raises ValueError (one line) for a
    base that is not a compiled composite or has neither part.
    """
    name = getattr(base, "name", base)
    if not getattr(base, "compiled", False):
        raise ValueError(f"rollout base {name!r} is not a composite of built-in kernels; allowed with sparse=True: "
                         "a compiled composite with an assignment or facility-location part")
    parts, sparse = {}, False
    for decision, part in base.parts.items():
        twin = SPARSE_TWINS.get(part.name)
        sparse = sparse or twin is not None or part.name in SPARSE_TWINS.values()
        if twin is None:
            parts[decision] = part
            continue
        hp = {f: float(part.hp[i]) for i, f in enumerate(K.HP_FIELDS)}
        parts[decision] = BuiltinDecision(decision, CODES[decision][twin], twin, seed=part.seed, **hp)
    if not sparse:
        raise ValueError(f"rollout base {name!r} has no part to solve on a sparse graph; allowed with sparse=True: "
                         f"a compiled composite with one of {', '.join(SPARSE_TWINS)} (or its sparse twin)")
    return Composite(**parts, name=f"{name}-sparse")


def spatial_twin(base: Any) -> Composite:
    """The compiled composite ``base`` with its positioning played by spatial averaging, its hyper-parameters kept.

    The cheaper policy of the ``sparse:`` presets' futures: on ``city`` a p-median solve costs
    more than the rest of a step. Spatial averaging reads the same demand history (``smoothing``,
    ``request_weight``), so the state the base keeps carries over. ValueError (one line) for a
    base that is not a compiled composite.
    """
    if not getattr(base, "compiled", False):
        raise ValueError(f"rollout base {getattr(base, 'name', base)!r} is not a composite of built-in kernels; "
                         "allowed: a compiled composite")
    part = base.parts["positioning"]
    hp = {f: float(part.hp[i]) for i, f in enumerate(K.HP_FIELDS)}
    spatial = BuiltinDecision("positioning", CODES["positioning"]["spatial"], "spatial", seed=part.seed, **hp)
    return Composite(base.parts["dispatch"], base.parts["workforce"], spatial, name=f"{base.name}-spatial")


def sparse_flag(value: Any) -> bool | str:
    """``value`` as the ``sparse`` knob (True, False or ``"auto"``); ValueError of one line otherwise."""
    if isinstance(value, str) and value == "auto":
        return value
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"rollout knob sparse = {value!r} is not allowed; allowed: True or False (play the "
                         "base's sparse twin, its assignment and p-median on the k nearest), or 'auto' (the sparse "
                         f"preset on a world of more than {AUTO_SPARSE_PAIRS:,} facility-person pairs, the dense base "
                         "otherwise)")
    return bool(value)


def plays_sparse(M: int, N: int) -> bool:
    """Whether ``sparse="auto"`` plays the sparse preset on a world of ``M`` facility and ``N`` personnel slots."""
    return M * N > AUTO_SPARSE_PAIRS


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
        budget: a preset of :data:`BUDGETS` for the knobs not given; ``sparse:PRESET`` is that
            preset with ``sparse=True``, ``decide="period"`` and ``futures`` the sparse twin's
            :func:`spatial_twin` (the registry's ``rollout-solver-sparse-tuned`` presets, for ``city``).
        sparse: play :func:`sparse_twin` of ``base`` (a bool); ``"auto"``: on a world larger than
            :data:`AUTO_SPARSE_PAIRS` (:func:`plays_sparse`, read from the first observation of each
            episode), what ``sparse:PRESET`` plays (the twin, ``decide="period"``, the twin's spatial
            futures unless ``futures`` is given), and otherwise exactly what ``sparse=False`` plays.
        decide: when to roll out (:data:`DECIDE`): ``"base"``, where the base hires or lets go
            and every R steps; ``"period"``, every R steps only (the base's other actions pass).
        futures: a compiled composite that plays the futures after their first step; None: the base.
        scenario: the public config of the world (a :class:`ScenarioConfig`); None: from
            :meth:`set_world` (the evaluator's), else built from the first observation.
        seed: the policy's own seed, mixed into its belief keys.
        name: the policy's name.
    """

    def __init__(self, base: Any, K: int | None = None, H: int | None = None, R: int | None = None,
                 budget: str = DEFAULT_BUDGET, scenario: ScenarioConfig | None = None, seed: int = 0,
                 name: str | None = None, sparse: bool | str = False, decide: str = "base", futures: Any = None):
        if isinstance(budget, str) and budget.startswith(SPARSE_PRESET):  # the city presets (module docstring)
            budget, sparse, decide = budget[len(SPARSE_PRESET):], True, "period"
            futures = spatial_twin(sparse_twin(base)) if futures is None else futures
        self.sparse_knob = sparse_flag(sparse)  # as given: True (a sparse: preset too), False or "auto"
        self._large = None  # sparse="auto": what a large world plays (base, decide, futures), else None
        if self.sparse_knob == "auto":
            twin = sparse_twin(base)
            self._large = (twin, "period", spatial_twin(twin) if futures is None else futures)
            sparse = False
        if sparse_flag(sparse):
            base = sparse_twin(base)
        if not getattr(base, "compiled", False):
            raise ValueError(f"rollout base {getattr(base, 'name', base)!r} is not a composite of built-in kernels; "
                             "allowed: a compiled composite (a registry composite or tuned file of one)")
        check_decide(decide)
        if futures is not None and not getattr(futures, "compiled", False):
            raise ValueError(f"rollout futures {getattr(futures, 'name', futures)!r} is not a composite of built-in "
                             "kernels; allowed: None (the base) or a compiled composite")
        name = name or f"rollout-{getattr(base, 'name', 'base')}"
        self.sparse, self.decide, self.futures = bool(sparse), decide, futures
        self._small = (base, decide, futures)  # what any world plays, or with sparse="auto" a small one
        super().__init__(base, K, H, R, budget, scenario, seed, name)

    # the name of before; the runner hands ``attach`` only to policies that read the trace
    attach = RolloutBase.set_world

    def reset(self, seeds: int | Sequence[int]) -> None:
        self._seeds = seeds_array(seeds)
        self.belief = None  # made at the first observation (its M and N, and the model if none was given)

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        _, B = start_belief(self, obs)
        M, N = obs["facilities"].shape[1], obs["personnel"].shape[1]
        if self._large is not None:  # sparse="auto": the world's size decides, each episode
            large = plays_sparse(M, N)
            self.base, self.decide, self.futures = self._large if large else self._small
            self.sparse = large
        codes, hp, pstate = self.base.compiled_plan(self._seeds, M, N)
        self.codes, self.hp, self.pstate = codes, hp, pstate
        # the futures' kernels: the base's, or the cheaper composite's (its state is the base's, copied per row)
        self.f_codes, self.f_hp = (codes, hp) if self.futures is None else self.futures.compiled_plan(self._seeds,
                                                                                                       M, N)[:2]
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
        decide = (t % self.R == 0) if self.decide == "period" else (w != 0) | (t % self.R == 0)
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
        score = roll_candidates(self.fork, self.H, self.f_codes, self.f_hp, self.pstate, self.fork_pstate,
                                self.buffers, env_idx, rows_a, d, p, literal=True)
        self.timing["decisions"] += len(envs)
        self.timing["rolls"] += n
        self.last_scores = pick_best(score, envs, cands, self.K, w, self.B)


def start_belief(policy: Any, obs: dict[str, np.ndarray]) -> tuple[ScenarioConfig, int]:
    """A lookahead's episode starts: its belief of the world (``policy.belief``) made and reset on its seeds.

    The world's public config is the policy's own (``set_world`` or ``scenario=``), else read from
    the first observation ``obs``. Returns the config and the number of environments B; a
    RuntimeError of one line when the policy was reset with another number of seeds.
    """
    config = policy.config or config_from_observation(obs)
    B = obs["facilities"].shape[0]
    if len(policy._seeds) != B:
        raise RuntimeError(f"{policy.name}: reset with {len(policy._seeds)} seed(s), observed {B} environment(s)")
    policy.belief = Belief(config)
    policy.belief.reset(policy._seeds, policy.seed)
    return config, B


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


__all__ = ["AUTO_SPARSE_PAIRS", "BUDGETS", "DECIDE", "DEFAULT_BUDGET", "KNOBS", "SPARSE_PRESET", "SPARSE_TWINS",
           "Rollout", "RolloutBase", "budget", "candidate_rows", "check_decide", "knob", "make", "pick_best",
           "plays_sparse", "sparse_flag", "sparse_twin", "spatial_twin"]
