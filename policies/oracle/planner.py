"""The hindsight planner: a shadow of the real episode, forked and rolled forward to score candidate actions.

A :class:`Planner` keeps a *shadow* ``Simulator(config, seeds)`` stepped with exactly the real
joint action (:meth:`Planner.record`, called by :class:`policies.Composite` after every
``act``); each ``act`` checks the shadow against the observation bit for bit and raises
:class:`ShadowDivergedError` if it differs. ``decide`` runs the base kernels, then scores the
workforce, positioning and dispatch candidates (:mod:`wfbench.policies.oracle.workforce`,
:mod:`~wfbench.policies.oracle.positioning`, :mod:`~wfbench.policies.oracle.dispatch`) by
compiled roll-forwards of a preallocated fork (:func:`wfbench.core.fork.copy_state`,
:func:`wfbench.policies.kernels.forward.roll_forward`); ``docs/hindsight.md``, "How the planner works".
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.kernels.forward import RollBuffers, roll_forward
from wfbench.policies.oracle.dispatch import dispatch_candidates, next_visit_fixes
from wfbench.policies.oracle.positioning import (
    demand_clients,
    hire_sites,
    nearest_slot,
    one_hot_map,
    release_targets,
)
from wfbench.policies.oracle.workforce import workforce_candidates
from wfbench.policies.protocol import DECISION_INDEX, Attached, as_obs, decision_key, hp_vector, seeds_array

from wfbench.core.actions import AGENTS
from wfbench.core.config import ScenarioConfig
from wfbench.core.fork import copy_state, fork
from wfbench.core.simulator import Simulator
from wfbench.core.state import EMPTY, IDLE, RETURNING

# the base kernel of each decision the planner makes itself
_OWN_BASE = {"dispatch": K.D_NEAREST, "workforce": K.W_NOOP, "positioning": K.P_SPATIAL}
# the kernel assumed for a decision made by a part the planner does not know (a user's policy)
_OTHER_DEFAULT = {"dispatch": K.D_NEAREST, "workforce": K.W_THRESHOLD, "positioning": K.P_SPATIAL}
_CHECKED = ("facilities", "personnel", "globals")


class ShadowDivergedError(RuntimeError):
    """The shadow simulator no longer shows what the policy observes."""


class Planner(Attached):
    """Hindsight planner for the decisions in ``decide`` (see the module docstring).

    Args:
        decide: the decisions it makes, a subset of ``("dispatch", "workforce", "positioning")``.
        dispatch_horizon: steps of each dispatch roll-forward; None: 40 when the planner
            also makes the workforce decision, 300 when a built-in workforce part does
            (chosen on the development seeds 1000-1009 of paper-64, ``docs/hindsight.md``).
        max_requests: open requests per environment that get alternatives.
        workforce_every: steps between two workforce decisions.
        workforce_horizon: steps of each workforce roll-forward (and of the known demand).
    """

    def __init__(self, decide: Sequence[str], dispatch_horizon: int | None = None, max_requests: int = 3,
                 workforce_every: int = 10, workforce_horizon: int = 150):
        given_horizon = dispatch_horizon
        if dispatch_horizon is None:
            dispatch_horizon = 40 if "workforce" in decide else 300
        bad = [d for d in decide if d not in AGENTS]
        if bad or not decide:
            raise ValueError(f"decide = {decide!r} is not allowed; allowed: a non-empty subset of {AGENTS}")
        for name, v in (("dispatch_horizon", dispatch_horizon), ("max_requests", max_requests),
                        ("workforce_every", workforce_every), ("workforce_horizon", workforce_horizon)):
            if type(v) is not int or v < 1:
                raise ValueError(f"{name} = {v!r} is not allowed; allowed: an integer >= 1")
        self.decide = tuple(d for d in AGENTS if d in decide)
        self._dispatch_horizon_given = given_horizon
        self.dispatch_horizon = dispatch_horizon
        self.max_requests = max_requests
        self.workforce_every = workforce_every
        self.workforce_horizon = workforce_horizon
        self.config: ScenarioConfig | None = None
        # kernel code, hyper-parameters and seed per decision (the parts of the composite it plays in)
        self.base = {d: (_OWN_BASE[d] if d in self.decide else _OTHER_DEFAULT[d], hp_vector({}, "oracle base"), 0)
                     for d in AGENTS}
        self.timing: dict[str, float] = {}
        # per environment, the hindsight value of each workforce action at the last step that scored them
        # (its roll-forward score minus the no-op's; NaN: not scored, e.g. masked), None at other steps
        self.workforce_values: np.ndarray | None = None
        self.shadow: Simulator | None = None
        self._reset_seeds: np.ndarray | None = None
        self._fresh = False

    def settings(self) -> dict[str, int | None]:
        """The settings it was made with (the dispatch horizon as given: None picks it by ``decide``)."""
        return {"dispatch_horizon": self._dispatch_horizon_given, "max_requests": self.max_requests,
                "workforce_every": self.workforce_every, "workforce_horizon": self.workforce_horizon}

    def use_part(self, decision: str, code: int, hp: np.ndarray, seed: int = 0) -> None:
        """A decision this planner does not make is made by a built-in kernel: model it exactly."""
        if decision in self.decide:
            raise ValueError(f"the planner makes the {decision} decision itself")
        self.base[decision] = (int(code), np.asarray(hp, dtype=np.float64).copy(), int(seed))

    # -- protocol ------------------------------------------------------------------------------
    def attach(self, config: ScenarioConfig) -> None:
        """Tell the planner the scenario (the runner does, before ``reset``, for policies that read the trace)."""
        super().attach(config)
        self._reset_seeds = None

    def reset(self, seeds: int | Sequence[int]) -> None:
        """Start the shadow of the coming batch (``attach`` first)."""
        self._attached()
        seeds = seeds_array(seeds)
        if self._fresh and self._reset_seeds is not None and np.array_equal(seeds, self._reset_seeds):
            return  # already reset for these seeds (the parts of a composite share this planner)
        c = self.config
        self.shadow = Simulator(c, [int(s) for s in seeds], keep_series=False, threads=1)
        self.shadow.reset()
        B, M, N = self.shadow.B, self.shadow.M, self.shadow.N
        self.B, self.M, self.N = B, M, N
        self.codes = np.array([self.base[d][0] for d in AGENTS], dtype=np.int64)
        self.hp = np.stack([self.base[d][1] for d in AGENTS])
        self.pstate = K.allocate_state(B, M, N)
        for d in AGENTS:
            for b, s in enumerate(seeds):
                self.pstate.keys[b, DECISION_INDEX[d]] = decision_key(int(s), self.base[d][2], d)
        width = max(1 + 3 * self.max_requests, 9)
        self.fork = fork(self.shadow, copies=width, keep_series=False, threads=1)
        self.fork_pstate = K.allocate_state(self.fork.B, M, N)
        self.buffers = RollBuffers(self.fork.B, M, N)
        self.fix_prob = c.base_fix_rate * np.asarray(c.level_multipliers, dtype=np.float64)
        self._joint: dict[str, np.ndarray] | None = None
        self._joint_t = -1
        self._recorded = True
        self._reset_seeds = seeds
        self._fresh = True
        self.timing = {"steps": 0.0, "act_s": 0.0, "shadow_s": 0.0, "base_s": 0.0, "workforce_s": 0.0,
                       "dispatch_s": 0.0, "workforce_rolls": 0.0, "dispatch_rolls": 0.0}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The joint action of this step (every decision; those not in ``decide`` are the base kernels')."""
        if self.shadow is None:
            raise RuntimeError("call reset(seeds) before act()")
        t = int(obs["t"][0])
        if self._joint is not None and self._joint_t == t:
            return self._joint  # another part of the same composite asks again
        start = time.perf_counter()
        self._fresh = False
        self.workforce_values = None
        self._advance_shadow(t)
        self._check(obs)
        t1 = time.perf_counter()
        B, M, N = self.B, self.M, self.N
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        K.act_batch(as_obs(obs), self.pstate, self.codes, self.hp, d, w, p, np.asarray(obs["t"], dtype=np.int64))
        t2 = time.perf_counter()
        if "workforce" in self.decide:
            if t % self.workforce_every == 0:
                self._decide_workforce(obs, d, w, p)
        elif "positioning" in self.decide and (w != 0).any():
            self._position_for(obs, d, w, p)
        t3 = time.perf_counter()
        if "dispatch" in self.decide:
            d = self._decide_dispatch(obs, d, w, p)
        t4 = time.perf_counter()
        self._joint = {"dispatch": d, "workforce": w, "positioning": p}
        self._joint_t = t
        self._recorded = False
        tm = self.timing
        tm["steps"] += 1
        tm["shadow_s"] += t1 - start
        tm["base_s"] += t2 - t1
        tm["workforce_s"] += t3 - t2
        tm["dispatch_s"] += t4 - t3
        tm["act_s"] += t4 - start
        return self._joint

    def record(self, actions: dict[str, np.ndarray]) -> None:
        """The joint action the episode takes at the step of the last ``act``: step the shadow with it."""
        if self.shadow is None or self._recorded or self._joint is None:
            return
        start = time.perf_counter()
        self.shadow.step(actions)
        self._recorded = True
        self.timing["shadow_s"] += time.perf_counter() - start

    # -- the shadow ----------------------------------------------------------------------------
    def _advance_shadow(self, t: int) -> None:
        s = self.shadow
        if s.t == t - 1 and not self._recorded and self._joint is not None:
            if set(self.decide) != set(AGENTS):
                raise ShadowDivergedError(
                    "a hindsight oracle that makes only some decisions must be told the joint action of every step: "
                    "use it inside policies.Composite, which calls record(actions) after act")
            s.step(self._joint)
            self._recorded = True
        if s.t != t:
            raise ShadowDivergedError(f"the oracle's shadow is at step {s.t}, the observation at step {t}: "
                                      "reset(seeds) before each batch and act once per step")

    def _check(self, obs: dict[str, np.ndarray]) -> None:
        mine = self.shadow.observe(with_masks=False)
        for key in _CHECKED:
            if not np.array_equal(mine[key], obs[key]):
                raise ShadowDivergedError(
                    f"the oracle's shadow differs from the observed world at step {self.shadow.t} ({key}): it was "
                    "attached to another scenario, reset with other seeds, or not told an action")

    # -- roll-forwards -------------------------------------------------------------------------
    def _roll(self, envs: np.ndarray, first_d: np.ndarray, first_w: np.ndarray, first_p: np.ndarray, steps: int,
              record: bool = False) -> np.ndarray:
        """Scores of candidates: row i copies env ``envs[i]`` of the shadow, then takes the given first action."""
        n = envs.shape[0]
        if n > self.fork.B:
            raise RuntimeError(f"{n} candidates exceed the fork's {self.fork.B} rows")
        copy_state(self.fork, self.shadow, envs)
        for src, dst in zip(self.pstate, self.fork_pstate, strict=True):
            np.take(src, envs, axis=0, out=dst[:n])
        buf = self.buffers
        buf.first_d[:n] = first_d
        buf.first_w[:n] = first_w
        buf.first_p[:n] = first_p
        score = roll_forward(self.fork, steps, self.codes, self.hp, self.fork_pstate, first=True, buffers=buf,
                             record=record, rows=n)
        return score[:n].copy()

    def _people(self, b: int):
        """Homes (h, 2), levels (h,) and releasable flags (h,) of the retained workforce of env b (shadow state)."""
        S = self.shadow.state
        st = S.per_status[b]
        keep = (st != EMPTY) & (S.per_leave[b] < 0)
        homes = np.stack([S.per_hx[b][keep], S.per_hy[b][keep]], axis=1)
        rel = (st[keep] >= IDLE) & (st[keep] <= RETURNING)
        return homes, S.per_level[b][keep], rel

    def _sites(self, b: int):
        S = self.shadow.state
        slots = np.flatnonzero(S.fac_active[b])
        return slots, np.stack([S.fac_x[b][slots], S.fac_y[b][slots]], axis=1)

    def _maps(self, row: int, b: int, fallback: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
        """Hire maps (p-median site, best addition) and let-go maps by level of env b.

        The demand is the one recorded in fork row ``row``.
        """
        buf = self.buffers
        cells, counts = demand_clients(buf.onset_xy[row], buf.n_onsets[row])
        slots, sites = self._sites(b)
        homes, levels, rel = self._people(b)
        M = self.M
        if cells.shape[0] == 0 or slots.size == 0:
            hire = [fallback]
        else:
            pm, gr = hire_sites(sites, homes, cells, counts)
            hire = [one_hot_map(M, 0, int(slots[pm]), fallback)]
            if gr != pm:
                hire.append(one_hot_map(M, 0, int(slots[gr]), fallback))
        targets = release_targets(homes, levels, rel, cells, counts)
        release: list[np.ndarray | None] = []
        for lv in range(3):
            if targets[lv] < 0:
                release.append(None)
            else:
                release.append(one_hot_map(M, 1, nearest_slot(slots, sites, homes[targets[lv]]), fallback))
        return hire, release

    def _decide_workforce(self, obs, d, w, p) -> None:
        B = self.B
        envs = np.arange(B, dtype=np.int64)
        zeros = np.zeros(B, dtype=np.int64)
        own_maps = "positioning" in self.decide
        noop = self._roll(envs, d, zeros, p, self.workforce_horizon, record=own_maps)
        rows_env, rows_w, rows_p = [], [], []
        for b in range(B):
            if own_maps:
                hire, release = self._maps(b, b, p[b])
            else:
                m = obs["workforce_mask"][b]
                hire, release = [p[b]], [p[b] if m[4 + lv] else None for lv in range(3)]
            for a, mp in workforce_candidates(obs["workforce_mask"][b], hire, release, p[b])[1:]:
                rows_env.append(b)
                rows_w.append(a)
                rows_p.append(mp)
        self.timing["workforce_rolls"] += B + len(rows_env)
        self.workforce_values = values = np.full((B, obs["workforce_mask"].shape[1]), np.nan)
        values[:, 0] = 0.0
        if not rows_env:
            return
        env_idx = np.asarray(rows_env, dtype=np.int64)
        scores = self._roll(env_idx, d[env_idx], np.asarray(rows_w, dtype=np.int64), np.stack(rows_p),
                            self.workforce_horizon)
        for i, b in enumerate(rows_env):
            a = rows_w[i]
            if not scores[i] - noop[b] <= values[b, a]:  # a hire keeps its best site (NaN: first seen)
                values[b, a] = scores[i] - noop[b]
        best = noop.copy()
        for i, b in enumerate(rows_env):
            if scores[i] > best[b]:
                best[b] = scores[i]
                w[b] = rows_w[i]
                p[b] = rows_p[i]

    def _position_for(self, obs, d, w, p) -> None:
        """Maps for the envs whose (other) workforce part hires or lets go this step."""
        envs = np.flatnonzero(w != 0).astype(np.int64)
        self._roll(envs, d[envs], np.zeros(envs.size, dtype=np.int64), p[envs], self.workforce_horizon, record=True)
        for i, b in enumerate(envs):
            hire, release = self._maps(i, b, p[b])
            a = int(w[b])
            if a <= 3:
                p[b] = hire[0]
            elif release[a - 4] is not None:
                p[b] = release[a - 4]

    def _decide_dispatch(self, obs, d, w, p) -> np.ndarray:
        S = self.shadow.state
        key = self.shadow.trace.key
        rows_env, rows_d = [], []
        for b in range(self.B):
            req = obs["requesting"][b]
            free = obs["dispatchable"][b]
            if not req.any() or not free.any():
                continue
            fixes = {}
            for f in np.flatnonzero(req):
                fixes[int(f)] = next_visit_fixes(key[b], int(f), int(S.fac_request[b, f]), int(S.fac_visits[b, f]),
                                                 self.fix_prob)
            fac_xy = np.stack([S.fac_x[b], S.fac_y[b]], axis=1)
            per_xy = np.stack([S.per_x[b], S.per_y[b]], axis=1)
            cands = dispatch_candidates(d[b], req, free, fac_xy, per_xy, S.per_level[b], fixes, self.max_requests)
            if len(cands) < 2:
                continue
            for c in cands:
                rows_env.append(b)
                rows_d.append(c)
        if not rows_env:
            return d
        self.timing["dispatch_rolls"] += len(rows_env)
        env_idx = np.asarray(rows_env, dtype=np.int64)
        scores = self._roll(env_idx, np.stack(rows_d), w[env_idx], p[env_idx], self.dispatch_horizon)
        out = d.copy()
        best: dict[int, float] = {}
        for i, b in enumerate(rows_env):
            if b not in best or scores[i] > best[b]:  # the base (first) wins ties
                best[b] = scores[i]
                out[b] = rows_d[i]
        return out
