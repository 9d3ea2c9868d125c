"""The best policy in hindsight: play every candidate on each seed's known future, then replay the best one.

:class:`BestInHindsight` is the registry's ``oracle``. At ``reset`` it plays every candidate
(``wfbench.policies.registry.oracle_candidates()``) on a private ``Simulator(config, seeds)``
and keeps per seed the one with the highest episode NSW (the first on a tie); ``act`` replays
that episode exactly: compiled candidates live, the others from their recorded actions.
Totals come from :mod:`wfbench.policies.oracle.cache` where it has them, and a candidate that
cannot win on any seed is stopped early (exact pruning). ``scores``, ``choice``, ``cached`` and
``timing`` say what happened. It reads the trace: not deployable. Why each step is exact:
``docs/hindsight.md``, "The oracle: the best policy in hindsight".
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.kernels.forward import roll_forward, roll_range
from wfbench.policies.oracle import cache as totals_cache
from wfbench.policies.oracle.episodes import Recording
from wfbench.policies.protocol import DECISION_INDEX, Attached, as_obs, seeds_array

from wfbench.core.actions import AGENTS, validate_actions
from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.core.state import METRICS

K_NSW = METRICS.index("nsw")
# prune a candidate only when it is below the best total by more than float rounding could explain
PRUNE_MARGIN = 1e-9


class BestInHindsight(Attached):
    """Per seed, the best of the candidate policies on that seed's known future (see the module docstring).

    Args:
        candidates: the candidates' names, in the order that breaks ties (the first wins).
        resolve: makes a fresh policy from a name (``wfbench.policies.registry.get``); a module-level
            function, so the oracle pickles for the process backend.
        name: its name in tables.
        replay: take totals from recorded episodes and committed pieces (a replaying reference).
        inputs: with ``replay``, the files besides code a candidate reads, by name
            (``wfbench.policies.registry.input_files``, a module-level function); a piece must
            have recorded reading them, byte for byte. None: none (a piece of a candidate that
            reads a checkpoint or tuned file is then never taken).
    """

    reads_trace = True
    decisions = AGENTS

    def __init__(self, candidates: Sequence[str], resolve: Callable[[str], Any], name: str = "oracle",
                 replay: bool = False, inputs: Callable[[str], list] | None = None):
        if not candidates:
            raise ValueError("a best-in-hindsight oracle needs at least one candidate")
        self.candidates = tuple(candidates)
        self.resolve = resolve
        self.name = name
        self.replay = bool(replay)  # totals from pieces and recorded episodes (wfbench.policies.oracle.replay)
        self.inputs = inputs
        self.sources: dict[str, dict[str, int]] = {}  # with replay: candidate -> where its seeds' totals came from
        self.skipped: list[tuple[str, str, str]] = []  # with replay: (candidate, piece, why) passed over
        self.config: ScenarioConfig | None = None
        self.seeds: np.ndarray | None = None
        self.scores: np.ndarray | None = None  # (B, candidates) episode NSW, NaN where stopped early
        self.choice: list[str] = []
        self.timing: dict[str, float] = {}
        self.cached: dict[str, int] = {}  # candidate -> seeds whose total came from the totals cache

    def __repr__(self) -> str:
        return f"BestInHindsight({self.name!r}, {len(self.candidates)} candidates)"

    # -- playing the candidates ------------------------------------------------------------------
    def reset(self, seeds: int | Sequence[int]) -> None:
        """Play every candidate on ``seeds`` and choose one per seed (``attach`` first)."""
        self._attached()
        seeds = seeds_array(seeds)
        if self.replay:
            from wfbench.policies.oracle.replay import reset_replaying

            reset_replaying(self, seeds)
            return
        c = self.config
        B, T = seeds.size, c.horizon
        self.seeds = seeds
        fresh = self._resolved()
        self.scores = np.full((B, len(self.candidates)), np.nan)
        best_total = np.full(B, -np.inf)
        best = np.full(B, -1, dtype=np.int64)
        kept: dict[int, tuple[str, Any]] = {}  # candidate -> ("live" or "pending", policy) or ("recorded", Recording)
        batch = totals_cache.batch_keys(seeds)  # a network's totals are keyed by the whole batch (cache.played_key)
        self.timing, self.cached = {}, {}
        for k, name in enumerate(self.candidates):
            start = time.perf_counter()
            policy = fresh.pop(name) if name in fresh else self.resolve(name)
            compiled = getattr(policy, "compiled", False)
            played = None if compiled else totals_cache.played_key(c, policy)
            total, found = totals_cache.lookup(played, seeds, batch) if played else (None, None)
            if compiled:
                (total, self.cached[name]), how = self._play_compiled(policy, seeds), ("live", policy)
            elif found is not None and found.all():
                # played on this very batch before: its actions are needed only if it is the best somewhere (below)
                self.cached[name], how = B, ("pending", policy)
            else:
                total, rec = self._play_recorded(policy, seeds, best_total)
                how, self.cached[name] = ("recorded", rec), 0
                if played is not None and not np.isnan(total).any():
                    totals_cache.store(played, seeds, batch, total)
            self.timing[name] = time.perf_counter() - start
            done = ~np.isnan(total)
            self.scores[done, k] = total[done] / T
            better = done & (total > best_total)
            if better.any():
                best_total[better] = total[better]
                best[better] = k
                kept[k] = how
            kept = {j: v for j, v in kept.items() if (best == j).any()}
        self.choice = [self.candidates[j] for j in best]
        self._groups = []
        for j, (kind, obj) in kept.items():
            rows = np.flatnonzero(best == j)
            if kind == "pending":  # a cached network is the best on some seeds: play it for its actions
                start = time.perf_counter()
                total, obj = self._play_recorded(obj, seeds, np.full(B, -np.inf))
                self.timing[self.candidates[j]] += time.perf_counter() - start
                if not np.array_equal(total[rows], best_total[rows]):
                    raise RuntimeError(f"the oracle's totals cache ({totals_cache.directory()}) disagrees with a "
                                       f"replay of {self.candidates[j]!r}: delete that folder")
                kind = "recorded"
            if kind == "live":
                obj = self.resolve(self.candidates[j])  # fresh: the played copy holds the end-of-episode state
                obj.reset(seeds[rows])
            self._groups.append((kind, obj, rows))

    def compile_ahead(self, cached: Callable[[Any], bool]) -> tuple[str, Callable, tuple] | None:
        """On a cold cache, what a second process may compile while this one compiles the roll-forward.

        The runner asks (``wfbench.harness.runner.start_compile_ahead``, after ``attach``): this
        process compiles the compiled candidates' roll-forward first, its longest compilation;
        meanwhile the second process compiles the built-in rules that the other candidates act
        with (:func:`act_plans`, :func:`compile_for_act`), which this one then loads from disk.
        ``cached(dispatcher)`` says whether numba's cache holds a compilation of it: none of the
        roll-forward is taken for cold. Changes nothing that runs; the candidates resolved here
        are the ones ``reset`` plays. None: warm, or nothing to compile ahead.
        """
        self._attached()
        if cached(roll_range):
            return None
        self._fresh = {name: self.resolve(name) for name in self.candidates}
        plans = act_plans(self._fresh.values())
        if not plans:
            return None
        return "the built-in rules the oracle's candidates act with", compile_for_act, (self.config, plans)

    def _resolved(self) -> dict[str, Any]:
        """The candidates :meth:`compile_ahead` resolved (fresh, not played yet), handed over once."""
        fresh, self._fresh = getattr(self, "_fresh", {}), {}
        return fresh

    def _play_compiled(self, policy: Any, seeds: np.ndarray) -> tuple[np.ndarray, int]:
        """Episode totals of NSW of a composite of built-in kernels, and how many seeds' came from the cache.

        The totals cache (:mod:`wfbench.policies.oracle.cache`) is asked first; only the
        seeds it does not hold are played, compiled, as one batch: a compiled candidate's
        total on a seed does not depend on its batch.
        """
        c = self.config
        codes, hp, pstate = policy.compiled_plan(seeds, c.max_facilities, c.max_personnel)
        key = totals_cache.policy_key(c, codes, hp)
        total, found = totals_cache.lookup(key, seeds, pstate.keys)
        if found.all():
            return total, int(found.sum())
        rows = np.flatnonzero(~found)
        sim = Simulator(c, [int(s) for s in seeds[rows]], keep_series=False, threads=1)
        sim.reset()
        codes, hp, pstate = policy.compiled_plan(seeds[rows], sim.M, sim.N)
        keys = pstate.keys.copy()  # before the episode (the kernels may advance them)
        roll_forward(sim, c.horizon, codes, hp, pstate)
        total[rows] = sim.state.totals[:, K_NSW].astype(np.float64)
        totals_cache.store(key, seeds[rows], keys, total[rows])
        return total, int(found.sum())

    def _play_recorded(self, policy: Any, seeds: np.ndarray, best_total: np.ndarray,
                       world: bool = False) -> tuple[np.ndarray, Recording]:
        """Episode totals of NSW of any policy played through ``act`` (NaN when stopped early), and its actions.

        With ``world``, a deployable policy with ``set_world`` is handed the public config first,
        as the runner hands it (``wfbench.harness.runner.public_world``): a lookahead plays then
        the episode it plays in an evaluation.
        """
        c = self.config
        T = c.horizon
        sim = Simulator(c, [int(s) for s in seeds], keep_series=False, threads=1)
        obs = sim.reset()
        if getattr(policy, "reads_trace", False):
            policy.attach(c)
        elif world and hasattr(policy, "set_world"):
            policy.set_world(ScenarioConfig.from_dict(c.to_dict()))
        policy.reset(sim.seeds)
        rec = Recording(sim.B, sim.M, sim.N, T)
        while not sim.done:
            t = sim.t
            d, w, p = validate_actions(policy.act(obs), sim.B, sim.M, sim.N)
            rec.add(t, d, w, p)
            sim.step({"dispatch": d, "workforce": w, "positioning": p})
            obs = sim.observe()
            reach = sim.state.totals[:, K_NSW] + (T - sim.t)  # NSW_t <= 1 at every step left
            if not sim.done and (reach < best_total - PRUNE_MARGIN).all():
                return np.full(sim.B, np.nan), rec
        rec.finish()
        return sim.state.totals[:, K_NSW].astype(np.float64), rec

    # -- replaying the choice --------------------------------------------------------------------
    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if self.seeds is None:
            raise RuntimeError("call attach(config) and reset(seeds) before act()")
        B, M = obs["requesting"].shape
        N = obs["personnel"].shape[1]
        t = int(obs["t"][0])
        if len(self._groups) == 1 and self._groups[0][0] == "live":
            return self._groups[0][1].act(obs)
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        for kind, obj, rows in self._groups:
            if kind == "recorded":
                d[rows], w[rows], p[rows] = obj.actions(t, rows)
            else:
                sub = obj.act({k: v[rows] for k, v in obs.items()})
                d[rows], w[rows], p[rows] = sub["dispatch"], sub["workforce"], sub["positioning"]
        return {"dispatch": d, "workforce": w, "positioning": p}


def act_plans(policies: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """The rule codes and hyper-parameters that the policies not played compiled pass to ``act_batch``, one per codes.

    The built-in parts of a composite that is not compiled whole act alone (their decision's code,
    the others 0); a planner's part acts with its planner's built-in base. Compiled composites
    are played by the roll-forward and are not listed.
    """
    plans: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}
    for policy in policies:
        if getattr(policy, "compiled", True) or not hasattr(policy, "parts"):
            continue
        for part in policy.parts.values():
            planner = getattr(part, "planner", None)
            if planner is not None and hasattr(planner, "base"):
                codes = np.array([planner.base[d][0] for d in AGENTS], dtype=np.int64)
                hp = np.stack([planner.base[d][1] for d in AGENTS])
            elif hasattr(part, "code") and getattr(part, "decision", None) in DECISION_INDEX:
                codes = np.zeros(3, dtype=np.int64)
                codes[DECISION_INDEX[part.decision]] = part.code
                hp = np.zeros((3, len(K.HP_FIELDS)))
                hp[DECISION_INDEX[part.decision]] = part.hp
            else:
                continue
            plans.setdefault(tuple(codes.tolist()), (codes, hp))
    return list(plans.values())


def compile_for_act(config: ScenarioConfig, plans: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
    """What a second process runs for :meth:`BestInHindsight.compile_ahead`: one seed, thrown away.

    ``act_batch`` runs each of ``plans`` on the first observation of a simulator of ``config``
    (as the candidates' own: no series, one thread), each compiled (or loaded) for the types the
    candidates pass, and cached; then the simulator steps and observes once.
    """
    sim = Simulator(config.replace(horizon=2), [0], keep_series=False, threads=1)
    obs = sim.reset()
    B, M, N = sim.B, sim.M, sim.N
    for codes, hp in plans:
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        K.act_batch(as_obs(obs), K.allocate_state(B, M, N), codes, hp, d, w, p, np.asarray(obs["t"], dtype=np.int64))
    sim.step({"dispatch": np.full((B, M), N, dtype=np.int64), "workforce": np.zeros(B, dtype=np.int64),
              "positioning": np.zeros((B, 2, M))})
    sim.observe()
