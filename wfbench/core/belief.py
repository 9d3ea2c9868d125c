"""Simulators built from what a policy sees: sampled worlds for deployable lookahead (issue #43).

Where :mod:`wfbench.core.fork` forks the *true* state (the hindsight oracles), a
:class:`Belief` keeps per environment only what the observations reveal, reconstructs the hidden
windows and timers from past observations (exact from ``t = 0``), and writes simulator states
that re-observe as the observation, every unobserved part drawn fresh from the public model
(:class:`PublicModel`, from the scenario's config; :func:`check_world` refuses another world's
observation) under the policy's own keys (:func:`belief_key`). Sample ``k`` of a step is one world
whatever is played in it: common random numbers across candidates. Nothing here reads a trace or
a true state. What comes from where: ``docs/policies.md``, "Simulators built from what a policy sees".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numba import njit

from wfbench.core import jit as _jit  # noqa: F401  (first: keys the numba cache of what follows)
from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.dynamics import write_metrics
from wfbench.core.observation_v2 import WORLD_DYNAMIC, WORLD_FEATURES, world_parameters
from wfbench.core.observe import (
    FAC_DOWNTIME,
    FAC_PERSON,
    FAC_REQUESTING,
    FAC_X,
    FAC_Y,
    G_AFD,
    G_HEAD,
    G_NSW,
    G_PUR,
    G_WC,
    PER_FACILITY,
    PER_HOME_X,
    PER_HOME_Y,
    PER_LEVEL,
    PER_UTILIZATION,
    PER_X,
    PER_Y,
)
from wfbench.core.rng import STREAM_FAILURE, exponential, key_from_seed, normal, uniform
from wfbench.core.schedule import RateSchedule
from wfbench.core.simulator import Simulator
from wfbench.core.state import (
    EMPTY,
    IDLE,
    RETURNING,
    SERVICING,
    TO_FACILITY,
)
from wfbench.core.trace import NEVER, Trace

# The belief's own purposes (the fork's simulator then uses the core's purposes under the row key)
STREAM_BELIEF_LEAVE = 41  # remaining lifetime of facility slot f
STREAM_BELIEF_ARRIVAL = 42  # n-th arrival: (gap, 0), (cell x, 1), (cell y, 2), (lifetime, 3), (site, 4), offsets 5, 6
STREAM_BELIEF_TIMER = 43  # (unused while the belief has seen every step; reserved for a prior on timers)
PURPOSE_BELIEF = 0xBE11EF  # the entropy that separates a belief key from the policy's decision keys

LAYOUT_UNIFORM, LAYOUT_SITES, LAYOUT_EMPIRICAL = 0, 1, 2
SEEN_CAPACITY = 4096  # facility cells remembered per environment (the empirical layout's sample)


class PublicModel(NamedTuple):
    """What the belief draws the unobserved from: the scenario's public model, in the compiled code's form."""

    grid_w: int
    grid_h: int
    horizon: int
    window: int
    service_time: int
    hire_delay: int
    fire_delay: int
    life_mean: float  # mean facility lifetime, steps (initial_facilities * churn_interval)
    max_cost: float
    churn_cum: np.ndarray  # (horizon,) float64 cumulative arrival hazard, churn_cum[0] = 0
    layout: int  # LAYOUT_UNIFORM, LAYOUT_SITES or LAYOUT_EMPIRICAL (clustered: towns unknown, cells seen)
    sites: np.ndarray  # (S, 3) float64 x, y, cumulative weight (sites layout)
    spread: float  # sites: jitter (cells)
    arrival_capacity: int  # arrivals a fork can hold (the trace's own guess, from t = 0)

    @classmethod
    def from_config(cls, config: ScenarioConfig) -> PublicModel:
        """The public model of ``config``: every rate schedule, the layout and the lifetimes."""
        c = require_config(config, "PublicModel.from_config")
        rate = c.churn_schedule.multipliers(c.horizon) / c.churn_interval
        rate[0] = 0.0
        cum = np.ascontiguousarray(np.cumsum(rate[: c.horizon]), dtype=np.float64)
        total = float(cum[-1])
        kind = {"uniform": LAYOUT_UNIFORM, "sites": LAYOUT_SITES}.get(c.layout.kind, LAYOUT_EMPIRICAL)
        sites = np.zeros((1, 3))
        if kind == LAYOUT_SITES:
            s = np.asarray(c.layout.sites, dtype=np.float64)
            sites = np.stack([s[:, 0], s[:, 1], np.cumsum(s[:, 2]) / s[:, 2].sum()], axis=1)
        return cls(grid_w=c.grid_width, grid_h=c.grid_height, horizon=c.horizon, window=c.window,
                   service_time=c.service_time, hire_delay=c.hire_delay, fire_delay=c.fire_delay,
                   life_mean=float(max(c.initial_facilities, 1) * c.churn_interval),
                   max_cost=float(c.max_workforce_cost), churn_cum=cum, layout=kind,
                   sites=np.ascontiguousarray(sites), spread=float(c.layout.jitter),
                   arrival_capacity=max(8, int(total + 6.0 * math.sqrt(total + 1.0) + 8)))


class History(NamedTuple):
    """Per environment: the last observation and what was reconstructed from the ones before."""

    key: np.ndarray  # (B,) uint64 the belief key (the policy's)
    t: np.ndarray  # (B,) int64 step of the last observation (-1: none)
    fac: np.ndarray  # (B, M, 7) float32 the last observation's facility features
    per: np.ndarray  # (B, N, 9) float32 ... personnel features
    fac_mask: np.ndarray  # (B, M) int8
    status: np.ndarray  # (B, N) int8
    notice: np.ndarray  # (B, N) int8
    glob: np.ndarray  # (B, 12) float32
    fac_since: np.ndarray  # (B, M) int64 step the facility arrived
    fac_ring: np.ndarray  # (B, M, W) uint8 down indicator per step of the window
    per_ready: np.ndarray  # (B, N) int64 step onboarding ends
    per_since: np.ndarray  # (B, N) int64 step work started
    per_leave: np.ndarray  # (B, N) int64 step the notice ends (-1 none)
    per_serv: np.ndarray  # (B, N) int64 first step the current visit was observed servicing
    per_ring: np.ndarray  # (B, N, W) uint8 work indicator per step of the window
    seen_xy: np.ndarray  # (B, SEEN_CAPACITY, 2) int64 cells of the facilities seen arriving (and at t = 0)
    n_seen: np.ndarray  # (B,) int64


def belief_key(env_seed: int, policy_seed: int = 0) -> np.uint64:
    """The belief key of an environment: from the seed a policy is reset with and its own seed, a purpose of its own.

    Under the hosted board the seed a policy is reset with is an opaque key (an HMAC of the
    episode's seed), so the belief's worlds are reproducible for a submission and tell
    nothing of the episode's.
    """
    return key_from_seed(int(env_seed), int(policy_seed), PURPOSE_BELIEF)


def check_world(obs: dict, model_config: ScenarioConfig) -> None:
    """Raise ``ValueError`` (one line) when the observation's public parameters are not those of ``model_config``."""
    world = obs.get("world")
    if world is None:
        return
    mine = world_parameters(model_config)
    fixed = [i for i, n in enumerate(WORLD_FEATURES) if n not in WORLD_DYNAMIC]
    got = np.asarray(world, dtype=np.float64)[:, fixed]
    bad = np.flatnonzero((got != mine[fixed]).any(axis=0))
    if bad.size:
        name = WORLD_FEATURES[fixed[bad[0]]]
        raise ValueError(f"the observation's world has {name} = {got[0, bad[0]]:g}, the belief's model "
                         f"{model_config.name!r} has {mine[fixed[bad[0]]]:g}: a belief needs the public config of the "
                         "world it observes")


def config_from_observation(obs: dict[str, np.ndarray], b: int = 0, name: str = "observed") -> ScenarioConfig:
    """The public model a policy can build from a step-0 observation alone (its ``world`` key and what it shows).

    Taken from ``world``: grid, speed, heat width, horizon, window, service time, delays,
    intervals, fix probabilities, salaries, utilization target, slots and the smallest
    headcount; from the observation: ``initial_facilities`` and ``initial_personnel`` (the
    active counts at step 0). Not observable, so assumed: the rate schedules hold their
    step-0 multipliers (a persistence forecast), facilities arrive uniformly on the grid,
    hires are placed at the heat map's maximum. Exact for a world that is constant, uniform
    and ``argmax`` (paper-64 and the Table 2 cells); pass the scenario's config otherwise.

    Raises:
        ValueError: no ``world`` key (observation version 1 carries no parameter of the world),
            or the observation is not of step 0.
    """
    if "world" not in obs:
        raise ValueError("the observation has no 'world' key (version 1 shows no parameter of the world); pass "
                         "the scenario's public config")
    if int(np.asarray(obs["t"]).reshape(-1)[b]) != 0:
        raise ValueError("config_from_observation needs the observation of step 0 (the initial counts)")
    w = dict(zip(WORLD_FEATURES, np.asarray(obs["world"], dtype=np.float64)[b].tolist(), strict=True))
    fix = np.array([w["fix_novice"], w["fix_mid"], w["fix_expert"]])
    base = float(fix.max()) if fix.max() > 0 else 1.0
    return ScenarioConfig(
        name=name, grid_width=int(w["grid_width"]), grid_height=int(w["grid_height"]),
        max_facilities=int(w["max_facilities"]), max_personnel=int(w["max_personnel"]),
        initial_facilities=int(np.asarray(obs["facility_mask"])[b].sum()),
        initial_personnel=int(np.asarray(obs["personnel_mask"])[b].sum()),
        min_personnel=int(w["min_personnel"]), horizon=int(w["horizon"]), request_interval=w["request_interval"],
        churn_interval=w["churn_interval"], base_fix_rate=base, level_multipliers=tuple((fix / base).tolist()),
        level_salaries=(w["salary_novice"], w["salary_mid"], w["salary_expert"]), speed=w["speed"],
        service_time=int(w["service_time"]), hire_delay=int(w["hire_delay"]), fire_delay=int(w["notice_delay"]),
        window=int(w["window"]), target_utilization=w["target_utilization"],
        utilization_tolerance=w["utilization_tolerance"], heat_sigma=w["heat_sigma"],
        request_schedule=_flat_schedule(w["request_multiplier"]),
        churn_schedule=_flat_schedule(w["churn_multiplier"]),
    )


def _flat_schedule(multiplier: float) -> RateSchedule:
    """The schedule that holds ``multiplier`` from step 0 on."""
    return RateSchedule() if multiplier == 1.0 else RateSchedule(kind="piecewise", times=(0,), values=(multiplier,))


# -- the compiled parts --------------------------------------------------------------------------------------------
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@njit(cache=True, inline="always")
def _mix(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def row_key(key, t, k):
    """The key of sample ``k`` at step ``t`` of the environment with belief key ``key``."""
    z = _mix(np.uint64(key) + _GOLDEN * np.uint64(t + 1))
    return _mix(z + _GOLDEN * np.uint64(k + 1) + np.uint64(0x5A3D))


@njit(cache=True, inline="always")
def _lifetime(key, stream, i, j, mean):
    """``max(1, ceil(mean * Exp(1)))`` steps: the trace's lifetime law."""
    return max(np.int64(1), np.int64(np.ceil(mean * exponential(key, stream, i, j, 0))))


@njit(cache=True)
def _remember(b, H, x, y):
    n = H.n_seen[b]
    if n < H.seen_xy.shape[1]:
        H.seen_xy[b, n, 0] = x
        H.seen_xy[b, n, 1] = y
    H.n_seen[b] = n + 1


@njit(cache=True)
def fold_observation(b, t, fac, per, fac_mask, status, notice, glob, H, m):
    """Fold the observation of environment ``b`` at step ``t`` into its history.

    Returns 0 (folded), 1 (a first observation after step 0: the history is unknown),
    2 (a step was skipped) or 3 (the same step again: nothing to do).
    """
    M = fac.shape[0]
    N = per.shape[0]
    W = m.window
    last = H.t[b]
    if t == 0:
        H.n_seen[b] = 0
        for f in range(M):
            H.fac_since[b, f] = 0
            H.fac_ring[b, f, :] = 0
            if fac_mask[f] == 1:
                _remember(b, H, np.int64(fac[f, FAC_X]), np.int64(fac[f, FAC_Y]))
        for p in range(N):
            H.per_ready[b, p] = 0
            H.per_since[b, p] = 0
            H.per_leave[b, p] = -1
            H.per_serv[b, p] = -1
            H.per_ring[b, p, :] = 0
    elif last < 0:
        return 1
    elif t == last:
        return 3
    elif t != last + 1:
        return 2
    else:
        w = (t - 1) % W
        for f in range(M):
            was = H.fac_mask[b, f] == 1
            H.fac_ring[b, f, w] = 1 if (was and H.fac[b, f, FAC_REQUESTING] > 0.5) else 0
            if fac_mask[f] != 1:
                H.fac_ring[b, f, :] = 0
                continue
            x = np.int64(fac[f, FAC_X])
            y = np.int64(fac[f, FAC_Y])
            new = (not was) or x != np.int64(H.fac[b, f, FAC_X]) or y != np.int64(H.fac[b, f, FAC_Y])
            if not new:  # an exit and an arrival on the same cell in one step: the observed downtime restarts
                denom = max(1, min(W, t - H.fac_since[b, f]))
                seen = np.int64(np.rint(np.float64(fac[f, FAC_DOWNTIME]) * denom))
                mine = np.int64(0)
                for k in range(W):
                    mine += H.fac_ring[b, f, k]
                if seen != mine:  # the window is exact for a facility that stayed: this one is new
                    new = True
            if new:
                H.fac_since[b, f] = t
                H.fac_ring[b, f, :] = 0
                _remember(b, H, x, y)
        for p in range(N):
            before = H.status[b, p]
            st = status[p]
            work = before == TO_FACILITY or before == SERVICING or before == RETURNING or (
                before == IDLE and st != IDLE and st != EMPTY)
            H.per_ring[b, p, w] = 1 if work else 0
            if st == EMPTY:
                H.per_ring[b, p, :] = 0
                H.per_leave[b, p] = -1
                H.per_serv[b, p] = -1
                continue
            if before == EMPTY:  # hired at t - 1
                H.per_ready[b, p] = t - 1 + m.hire_delay
                H.per_since[b, p] = t - 1 + m.hire_delay
                H.per_leave[b, p] = -1
                H.per_ring[b, p, :] = 0
            if notice[p] == 1 and H.notice[b, p] == 0:  # let go at t - 1
                H.per_leave[b, p] = t - 1 + m.fire_delay
            if st == SERVICING and before != SERVICING:
                H.per_serv[b, p] = t
            since = H.per_since[b, p]
            if st >= IDLE and t > since:  # the observed utilization is this window's sum: check the newest term
                denom = max(1, min(W, t - since))
                seen = np.int64(np.rint(np.float64(per[p, PER_UTILIZATION]) * denom))
                mine = np.int64(0)
                for k in range(W):
                    mine += H.per_ring[b, p, k]
                if seen != mine and 0 <= H.per_ring[b, p, w] + seen - mine <= 1:
                    H.per_ring[b, p, w] = np.uint8(H.per_ring[b, p, w] + seen - mine)
    H.t[b] = t
    H.fac[b] = fac
    H.per[b] = per
    H.fac_mask[b] = fac_mask
    H.status[b] = status
    H.notice[b] = notice
    H.glob[b] = glob
    return 0


@njit(cache=True)
def _arrival_cell(key, n, b, H, m):
    if m.layout == LAYOUT_SITES:
        u = uniform(key, STREAM_BELIEF_ARRIVAL, n, 4, 0)
        j = 0
        while j < m.sites.shape[0] - 1 and m.sites[j, 2] <= u:
            j += 1
        x = np.rint(m.sites[j, 0] + m.spread * normal(key, STREAM_BELIEF_ARRIVAL, n, 5, 0))
        y = np.rint(m.sites[j, 1] + m.spread * normal(key, STREAM_BELIEF_ARRIVAL, n, 6, 0))
        return min(max(np.int64(x), 0), m.grid_w - 1), min(max(np.int64(y), 0), m.grid_h - 1)
    if m.layout == LAYOUT_EMPIRICAL and H.n_seen[b] > 0:
        n_seen = min(H.n_seen[b], H.seen_xy.shape[1])
        j = np.int64(uniform(key, STREAM_BELIEF_ARRIVAL, n, 4, 0) * n_seen)
        return H.seen_xy[b, j, 0], H.seen_xy[b, j, 1]
    x = np.int64(uniform(key, STREAM_BELIEF_ARRIVAL, n, 1, 0) * m.grid_w)
    y = np.int64(uniform(key, STREAM_BELIEF_ARRIVAL, n, 2, 0) * m.grid_h)
    return x, y


@njit(cache=True, inline="always")
def _copy_ring(src, dst, b, i, x, on, W):
    """Slot ``x``'s window of 0/1 flags from ``src[b, x]`` into ``dst[i, x]`` (zeros when not ``on``); its sum."""
    total = np.int64(0)
    for j in range(W):
        v = src[b, x, j] if on else np.uint8(0)
        dst[i, x, j] = v
        total += v
    return total


@njit(cache=True)
def fill_row(i, b, k, end, H, S, Tr, m):
    """Row ``i`` of the fork's state and trace: sample ``k`` of environment ``b``'s belief, arrivals up to ``end``."""
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    W = m.window
    t = H.t[b]
    key = row_key(H.key[b], t, k)
    Tr.key[i] = key
    Tr.seed[i] = 0
    S.t[i] = t
    S.arr_ptr[i] = 0
    S.n_hires[i] = 0
    for f in range(M):
        on = H.fac_mask[b, f] == 1
        S.fac_active[i, f] = on
        S.fac_sum[i, f] = _copy_ring(H.fac_ring, S.fac_ring, b, i, f, on, W)
        S.fac_visits[i, f] = 0
        S.fac_ok_since[i, f] = t
        if on:
            down = H.fac[b, f, FAC_REQUESTING] > 0.5
            S.fac_x[i, f] = np.int64(H.fac[b, f, FAC_X])
            S.fac_y[i, f] = np.int64(H.fac[b, f, FAC_Y])
            S.fac_down[i, f] = down
            S.fac_assigned[i, f] = np.int64(H.fac[b, f, FAC_PERSON])
            S.fac_since[i, f] = H.fac_since[b, f]
            S.fac_leave[i, f] = t + _lifetime(key, STREAM_BELIEF_LEAVE, f, 0, m.life_mean)
            if down:
                S.fac_hazard[i, f] = 0.0
                S.fac_draws[i, f] = 0
                S.fac_request[i, f] = 0
            else:  # the clock's remaining hazard: Exp(1), drawn as the simulator draws a clock
                S.fac_hazard[i, f] = exponential(key, STREAM_FAILURE, f, 0, 0)
                S.fac_draws[i, f] = 1
                S.fac_request[i, f] = -1
        else:
            S.fac_x[i, f] = 0
            S.fac_y[i, f] = 0
            S.fac_down[i, f] = False
            S.fac_assigned[i, f] = -1
            S.fac_since[i, f] = 0
            S.fac_leave[i, f] = 0
            S.fac_hazard[i, f] = 0.0
            S.fac_draws[i, f] = 0
            S.fac_request[i, f] = -1
    for p in range(N):
        st = np.int64(H.status[b, p])
        S.per_status[i, p] = st
        S.per_dispatched[i, p] = -1
        on = st != EMPTY
        S.per_sum[i, p] = _copy_ring(H.per_ring, S.per_ring, b, i, p, on, W)
        if on:
            S.per_level[i, p] = np.int64(H.per[b, p, PER_LEVEL])
            S.per_hx[i, p] = np.int64(H.per[b, p, PER_HOME_X])
            S.per_hy[i, p] = np.int64(H.per[b, p, PER_HOME_Y])
            S.per_x[i, p] = np.float64(H.per[b, p, PER_X])
            S.per_y[i, p] = np.float64(H.per[b, p, PER_Y])
            S.per_target[i, p] = np.int64(H.per[b, p, PER_FACILITY]) if (st == TO_FACILITY or st == SERVICING) else -1
            S.per_timer[i, p] = max(1, m.service_time - (t - H.per_serv[b, p])) if st == SERVICING else 0
            S.per_ready[i, p] = H.per_ready[b, p]
            S.per_since[i, p] = H.per_since[b, p]
            S.per_leave[i, p] = H.per_leave[b, p] if H.notice[b, p] == 1 else -1
        else:
            S.per_level[i, p] = 0
            S.per_hx[i, p] = 0
            S.per_hy[i, p] = 0
            S.per_x[i, p] = 0.0
            S.per_y[i, p] = 0.0
            S.per_target[i, p] = -1
            S.per_timer[i, p] = 0
            S.per_ready[i, p] = 0
            S.per_since[i, p] = 0
            S.per_leave[i, p] = -1
    S.counters[i, :] = 0
    S.totals[i, :] = 0.0
    g = H.glob[b]
    row = S.last[i]
    row[:] = 0.0
    wc = np.float64(g[G_WC]) * m.max_cost
    afd = np.float64(g[G_AFD])
    nsw = np.float64(g[G_NSW])
    u_wc = 1.0 - wc / m.max_cost
    u_afd = 1.0 - afd
    u_pur = nsw ** 3 / max(u_wc * u_afd, 1e-300)
    head = np.float64(np.rint(np.float64(g[G_HEAD]) * N))
    write_metrics(row, wc, np.float64(g[G_PUR]), afd, nsw, u_wc, u_pur, u_afd, head)
    # arrivals from t + 1 to end: a Poisson process on the cumulative hazard's scale
    A = Tr.arr_t.shape[1]
    n = 0
    if t < end:
        cum = m.churn_cum
        point = cum[t]
        stop = cum[min(end, cum.shape[0] - 1)]
        while n < A:
            point += exponential(key, STREAM_BELIEF_ARRIVAL, n, 0, 0)
            if point > stop:
                break
            s = np.searchsorted(cum, point)
            x, y = _arrival_cell(key, n, b, H, m)
            Tr.arr_t[i, n] = s
            Tr.arr_x[i, n] = x
            Tr.arr_y[i, n] = y
            Tr.arr_leave[i, n] = s + _lifetime(key, STREAM_BELIEF_ARRIVAL, n, 3, m.life_mean)
            n += 1
    for a in range(n, A):
        Tr.arr_t[i, a] = NEVER
        Tr.arr_x[i, a] = 0
        Tr.arr_y[i, a] = 0
        Tr.arr_leave[i, a] = NEVER


@njit(cache=True, nogil=True)
def fill_rows(envs, samples, end, H, S, Tr, m):
    """Rows 0..len(envs)-1 of the fork: row i is sample ``samples[i]`` of environment ``envs[i]``."""
    for i in range(envs.shape[0]):
        fill_row(i, envs[i], samples[i], end[i], H, S, Tr, m)


@njit(cache=True)
def observe_batch(t, fac, per, fac_mask, status, notice, glob, H, m, codes):
    for b in range(t.shape[0]):
        codes[b] = fold_observation(b, t[b], fac[b], per[b], fac_mask[b], status[b], notice[b], glob[b], H, m)


# -- the belief ----------------------------------------------------------------------------------------------------
class Belief:
    """What a policy knows of B episodes, from their observations alone; simulators sampled from it.

    Args:
        config: the scenario's public :class:`ScenarioConfig`:
            the model the unobserved is drawn from (:class:`PublicModel`).

    Use: :meth:`reset` with the seeds (or opaque keys) the policy was reset with,
    :meth:`update` with every observation from step 0 on, then :meth:`simulator` once
    (a fork of some rows, reused) and :meth:`sample_into` at each decision.
    """

    def __init__(self, config: ScenarioConfig):
        self.config = require_config(config, "Belief")
        self.model = PublicModel.from_config(self.config)
        self.B = 0
        self.H: History | None = None

    def reset(self, seeds: Sequence[int], policy_seed: int = 0) -> None:
        """Start B episodes; their belief keys come from ``seeds`` (:func:`belief_key`)."""
        keys = np.array([belief_key(int(s), policy_seed) for s in np.atleast_1d(np.asarray(seeds))], dtype=np.uint64)
        self.reset_keys(keys)

    def reset_keys(self, keys: np.ndarray) -> None:
        """Start B episodes with the given belief keys (B,) uint64."""
        keys = np.ascontiguousarray(np.atleast_1d(keys), dtype=np.uint64)
        c = self.config
        B, M, N, W = keys.shape[0], c.max_facilities, c.max_personnel, c.window
        z = lambda *s, d=np.int64: np.zeros(s, dtype=d)  # noqa: E731
        self.B = B
        self.H = History(
            key=keys, t=np.full(B, -1, dtype=np.int64), fac=z(B, M, 7, d=np.float32), per=z(B, N, 9, d=np.float32),
            fac_mask=z(B, M, d=np.int8), status=z(B, N, d=np.int8), notice=z(B, N, d=np.int8),
            glob=z(B, 12, d=np.float32), fac_since=z(B, M), fac_ring=z(B, M, W, d=np.uint8), per_ready=z(B, N),
            per_since=z(B, N), per_leave=np.full((B, N), -1, dtype=np.int64), per_serv=np.full((B, N), -1, np.int64),
            per_ring=z(B, N, W, d=np.uint8), seen_xy=z(B, SEEN_CAPACITY, 2), n_seen=z(B),
        )
        self._codes = np.zeros(B, dtype=np.int64)

    @property
    def t(self) -> np.ndarray:
        """(B,) the step of each environment's last observation (-1: none yet)."""
        return self.H.t

    def update(self, obs: dict[str, np.ndarray]) -> None:
        """Fold one batched observation in (every step from 0; the same step twice is a no-op).

        Raises:
            RuntimeError: not reset, or the batch size differs.
            ValueError: an observation of another world, a first observation after step 0,
                or a step skipped (the reconstructed windows would be wrong).
        """
        if self.H is None:
            raise RuntimeError("Belief.reset(seeds) before update(obs)")
        t = np.ascontiguousarray(np.broadcast_to(np.asarray(obs["t"], dtype=np.int64), (self.B,)))
        if obs["facilities"].shape[0] != self.B:
            raise RuntimeError(f"an observation of {obs['facilities'].shape[0]} environments; the belief was reset "
                               f"with {self.B}")
        if (t == 0).any():
            check_world(obs, self.config)
        codes = self._codes
        observe_batch(t, obs["facilities"], obs["personnel"], obs["facility_mask"], obs["personnel_status"],
                      obs["under_notice"], obs["globals"], self.H, self.model, codes)
        if (codes == 1).any():
            b = int(np.argmax(codes == 1))
            raise ValueError(f"Belief.update: environment {b}'s first observation is at step {int(t[b])}; allowed: "
                             "every observation from step 0 (the history it reconstructs starts there)")
        if (codes == 2).any():
            b = int(np.argmax(codes == 2))
            raise ValueError(f"Belief.update: environment {b} jumped to step {int(t[b])}; allowed: every step's "
                             "observation, in order")

    def simulator(self, rows: int, threads: int = 1) -> Simulator:
        """A simulator of ``rows`` environments for :meth:`sample_into` (allocate once, refill at every decision).

        Its trace is the belief's own arrays (no episode's trace is ever generated for it).
        """
        if type(rows) is not int or rows < 1:
            raise ValueError(f"rows = {rows!r} is not allowed; allowed: an integer >= 1")
        c = self.config
        sim = Simulator(c, [0] * rows, keep_series=False, threads=threads)
        M, N, A = c.max_facilities, c.max_personnel, self.model.arrival_capacity
        zi = lambda *s: np.zeros(s, dtype=np.int64)  # noqa: E731
        sim.trace = Trace(seed=zi(rows), key=np.zeros(rows, dtype=np.uint64), fac0_active=np.zeros((rows, M), bool),
                          fac0_x=zi(rows, M), fac0_y=zi(rows, M), fac0_leave=zi(rows, M),
                          per0_active=np.zeros((rows, N), bool), per0_x=zi(rows, N), per0_y=zi(rows, N),
                          per0_level=zi(rows, N), arr_t=np.full((rows, A), NEVER, dtype=np.int64),
                          arr_x=zi(rows, A), arr_y=zi(rows, A), arr_leave=np.full((rows, A), NEVER, dtype=np.int64))
        sim.reset()  # ready to step: every row is then overwritten by sample_into
        return sim

    def sample_into(self, sim: Simulator, envs: np.ndarray, samples: np.ndarray, steps: int | None = None) -> None:
        """Rows 0..len(envs)-1 of ``sim`` become sample ``samples[i]`` of environment ``envs[i]`` at its last step.

        ``steps``: arrivals are drawn up to ``t + steps`` (the horizon when None), enough for a
        roll-forward of that many steps. Sample k of an environment at a step is the same world
        whichever row it is written to (common random numbers across candidates).
        """
        envs = np.ascontiguousarray(envs, dtype=np.int64)
        samples = np.ascontiguousarray(samples, dtype=np.int64)
        if envs.shape != samples.shape or envs.ndim != 1 or not 0 < envs.shape[0] <= sim.B:
            raise ValueError(f"envs {envs.shape} and samples {samples.shape}: allowed: two 1-D arrays of the same "
                             f"length, 1..{sim.B}")
        t = self.H.t[envs]
        if (t < 0).any():
            raise RuntimeError("Belief.update(obs) before sampling: an environment has no observation yet")
        horizon = self.config.horizon
        end = np.minimum(t + (horizon if steps is None else int(steps)), horizon - 1)
        fill_rows(envs, samples, end, self.H, sim.state, sim.trace, self.model)

    def sample(self, envs: Sequence[int] | None = None, copies: int = 1, steps: int | None = None) -> Simulator:
        """A new simulator holding ``copies`` samples of each of ``envs`` (all when None), rows grouped by env."""
        envs = np.arange(self.B) if envs is None else np.atleast_1d(np.asarray(envs, dtype=np.int64))
        idx = np.repeat(envs, copies).astype(np.int64)
        k = np.tile(np.arange(copies, dtype=np.int64), envs.shape[0])
        sim = self.simulator(int(idx.shape[0]))
        self.sample_into(sim, idx, k, steps)
        return sim


__all__ = ["Belief", "History", "PublicModel", "belief_key", "check_world", "config_from_observation", "row_key"]
