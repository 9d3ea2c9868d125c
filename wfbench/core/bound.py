"""A proven upper bound on the episode score, computed from the trace and the config alone.

No policy, oracles included, can score more than :func:`score_upper_bound` on a seed;
:func:`bound_parts` returns the pieces. In short: nobody works before the episode's first
failure ``t*`` (known from the trace), the workforce cost is bounded below per step by the
cheapest salaries the let-go rules can leave, each facility's downtime is bounded below by an
alternating process of known clocks and fastest repairs, and Hölder with exponents (3/2, 3)
combines them. A pure function of ``(config, seed)``. The argument, fact by fact:
``docs/hindsight.md``, "The upper bound".
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numba import njit

from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.rng import STREAM_FAILURE, STREAM_REPAIR, exponential, uniform
from wfbench.core.trace import trace as make_trace

_NO_FAILURE = -1
_MAX_VISITS = 256  # a request that needs more visits than this is counted as needing this many
_REL = 1e-9  # safety margins on the floating-point failure times of later cycles (see _threshold)
_ABS = 1e-12


class BoundParts(NamedTuple):
    """The pieces of the bound of one seed.

    Attributes:
        bound: the upper bound on the episode score.
        per_step: the bound without the downtime part, ``(1/T) sum_t a_t^(1/3)``
            (also valid; ``bound`` is the smaller of the two).
        first_failure: ``t*``, the step of the first failure of the episode (the
            horizon when nothing fails: the score is then 0).
        wc_utility: the per-step upper bound on ``u_WC``.
        pur_utility: the per-step upper bound on ``u_PUR`` (it binds early in the episode only).
        step_bound: ``a_t``, the per-step bound on ``u_WC * u_PUR`` (0 before ``t*``).
        downtime_sum: the lower bound on ``sum_{t >= t*} AFD_t``.
        downtime_mean: ``downtime_sum / T``.
    """

    bound: float
    per_step: float
    first_failure: int
    wc_utility: np.ndarray
    pur_utility: np.ndarray
    step_bound: np.ndarray
    downtime_sum: float
    downtime_mean: float


# -- the facility process that no decision changes ---------------------------------------------------
def occupancies(config: ScenarioConfig, tr) -> list[tuple[int, int, int]]:
    """Every activation of a facility slot in one episode, in the order it happens.

    Exits and arrivals come from the trace, and an arrival takes the lowest free slot
    (exits of a step come before its arrivals), so which slot holds which facility when
    is exogenous.

    Args:
        config: the scenario.
        tr: a single-episode :class:`wfbench.core.trace.Trace` (batch size 1).

    Returns:
        ``(slot, start, end)`` per activation: active on steps ``start .. end - 1``
        (``end`` is its exit step, capped at the horizon). Dropped arrivals are absent.
    """
    T = config.horizon
    M = config.max_facilities
    leave = np.full(M, -1, dtype=np.int64)  # exit step of the current occupant, -1 when the slot never held one
    out = []
    for f in range(M):
        if tr.fac0_active[0, f]:
            leave[f] = tr.fac0_leave[0, f]
            out.append((f, 0, int(min(leave[f], T))))
    for a in range(tr.arr_t.shape[1]):
        t = int(tr.arr_t[0, a])
        if t >= T:
            break
        free = np.flatnonzero(leave <= t)  # never used (-1) or exited at or before t
        if free.size == 0:
            continue  # dropped
        f = int(free[0])
        leave[f] = tr.arr_leave[0, a]
        out.append((f, t, int(min(leave[f], T))))
    return out


@njit(cache=True)
def _first_failure(key, f, draw, start, end, hazard):
    """The step the activation fails first, replicating the simulator's arithmetic; -1 if not before ``end``."""
    h = exponential(key, STREAM_FAILURE, f, draw, 0)
    for t in range(start + 1, end):
        h -= hazard[t]
        if h <= 0.0:
            return t
    return _NO_FAILURE


@njit(cache=True)
def _min_visits(key, f, request, p_best):
    """The fewest visits that can fix ``request`` of slot ``f``: the first draw below the best fix probability."""
    for v in range(_MAX_VISITS):
        if uniform(key, STREAM_REPAIR, f, request, v) < p_best:
            return v + 1
    return _MAX_VISITS


@njit(cache=True)
def _threshold(e, upper):
    """``e`` inflated (the latest the simulator's float arithmetic can fail) or deflated (the earliest)."""
    return e * (1.0 + _REL) + _ABS if upper else e * (1.0 - _REL) - _ABS


@njit(cache=True)
def _tau(cum, rho, thr, end):
    """First step t in (rho, end) whose hazard summed over ``rho + 1 .. t`` reaches ``thr``; ``end`` if none."""
    for t in range(rho + 1, end):
        if cum[t] - cum[rho] >= thr:
            return t
    return end


@njit(cache=True)
def _longest_up(cum, rho_min, thr, end):
    """The longest operational run after a repair at any step rho in ``[rho_min, end - 2]``, capped at the exit.

    After a repair at rho the facility is operational on ``rho + 1 .. tau(rho) - 1``;
    ``tau`` does not decrease with rho, so one forward scan finds every ``tau(rho)``.
    """
    longest = 0
    t = rho_min + 1
    for rho in range(rho_min, end - 1):
        if t <= rho:
            t = rho + 1
        while t < end and cum[t] - cum[rho] < thr:
            t += 1
        longest = max(longest, t - rho - 1)
    return longest


@njit(cache=True)
def _min_down_profile(key, f, draw0, start, end, tau0, cum, service_time, p_best, out):
    """Write into ``out[start:end]`` the down indicators of the bounding process of one activation.

    The activation's first failure is ``tau0`` (exact). Request k needs at least
    ``(service_time + 1) * V_k`` down steps; the operational period after the k-th
    repair is at most the longest the (k+1)-th clock allows for any repair step the
    simulator can reach (``rho >= rho_min``, ``rho_min`` from the shortest periods),
    capped at the exit.
    """
    tau_b = tau0  # failure step of the bounding process
    tau_min = tau0  # earliest failure step of the same cycle under any policy
    k = 0
    while tau_b < end:
        d = (service_time + 1) * _min_visits(key, f, k, p_best)
        for s in range(tau_b, min(tau_b + d, end)):
            out[s] = 1
        rho_b = tau_b + d - 1  # repair step of the bounding process
        rho_min = tau_min + d - 1  # earliest repair step of request k under any policy
        if rho_b >= end - 1 or rho_min >= end - 1:
            return
        k += 1
        e = exponential(key, STREAM_FAILURE, f, draw0 + k, 0)
        tau_b = rho_b + 1 + _longest_up(cum, rho_min, _threshold(e, True), end)
        tau_min = _tau(cum, rho_min, _threshold(e, False), end)


@njit(cache=True)
def _weights(start, end, in_s, n_active, window):
    """Per down step s of an activation, its weight in ``sum_{t in S} AFD_t``, replaced by the running minimum.

    A down step s of the facility counts ``1 / (n_t * min(W, t - start + 1))`` in
    ``AFD_t`` for every t in ``[s, s + W - 1]`` while the facility is active.
    """
    n = end - start
    w = np.zeros(n + 1)
    for i in range(n):
        t = start + i
        if in_s[t] and n_active[t] > 0:
            w[i] = 1.0 / (n_active[t] * min(window, i + 1))
    csum = np.zeros(n + 1)
    for i in range(n):
        csum[i + 1] = csum[i] + w[i]
    c = np.zeros(n)
    run = np.inf
    for i in range(n):
        hi = min(i + window, n)
        v = csum[hi] - csum[i]
        run = min(run, v)
        c[i] = run
    return c


def _downtime_lower_bound(config: ScenarioConfig, tr, occ, cum, t_first, in_s):
    """``sum_{t in S} AFD_t`` from below; ``t_first`` from :func:`_first_failures`, ``in_s`` the mask of S."""
    T = config.horizon
    key = tr.key[0]
    n_active = np.zeros(T + 1, dtype=np.int64)
    for _, a, e in occ:
        n_active[a] += 1
        n_active[e] -= 1
    n_active = np.cumsum(n_active)[:T]
    p_best = config.base_fix_rate * max(config.level_multipliers)
    draws = {}
    failed = set()
    total = 0.0
    for (f, a, e), tau0 in zip(occ, t_first, strict=True):
        j = draws.get(f, 0)
        draws[f] = j + 1
        if f in failed or tau0 < 0:
            continue
        failed.add(f)
        down = np.zeros(T, dtype=np.int8)
        _min_down_profile(key, f, j, a, e, tau0, cum, config.service_time, p_best, down)
        c = _weights(a, e, in_s, n_active, config.window)
        total += float(np.dot(down[a:e], c))
    return total


def _first_failures(config: ScenarioConfig, tr, occ, hazard) -> list[int]:
    """Per activation its first failure step when it is exogenous (-1: none before its exit; -2: not known)."""
    key = tr.key[0]
    draws: dict[int, int] = {}
    failed: set[int] = set()
    out = []
    for f, a, e in occ:
        j = draws.get(f, 0)
        draws[f] = j + 1
        if f in failed:
            out.append(-2)  # the slot has failed before: its draw indices depend on the policy
            continue
        tau = int(_first_failure(key, f, j, a, e, hazard))
        if tau >= 0:
            failed.add(f)
        out.append(tau)
    return out


def _wc_utility_bound(config: ScenarioConfig, tr) -> np.ndarray:
    """Per step t, an upper bound on ``u_WC,t`` for every policy."""
    T = config.horizon
    sal = np.asarray(config.level_salaries, dtype=np.float64)
    levels = tr.per0_level[0][tr.per0_active[0]]
    cheapest = np.sort(sal[levels])  # initial salaries, cheapest first
    n0 = cheapest.size
    csum = np.concatenate([[0.0], np.cumsum(cheapest)])
    t = np.arange(T)
    k = np.clip(t - max(config.fire_delay, 1) + 1, 0, n0)  # initial people who can have left by step t
    floor = config.min_personnel * sal.min()
    wc = np.maximum(csum[n0 - k], floor)
    return np.clip(1.0 - wc / config.max_workforce_cost, 0.0, 1.0)


def _pur_utility_bound(config: ScenarioConfig, tr, occ, t_first) -> np.ndarray:
    """Per step t, an upper bound on ``u_PUR,t`` early in the episode (1 once it no longer binds).

    Only people who have been dispatched can have worked, and a facility takes a new
    dispatch at most every ``service_time + 1`` steps from the step it can first be down
    (its known first failure; the step after activation when that is not known). At
    least ``n0 - k_t`` initial people are onboarded, so ``PUR_t <= X_t / (n0 - k_t)``
    with ``X_t`` the most dispatches there can have been by t; ``u_PUR`` does not
    decrease below the target, so ``u_PUR,t <= u_PUR(min(that, target))``.
    """
    T = config.horizon
    step = config.service_time + 1
    t = np.arange(T)
    x = np.zeros(T)
    for (_, a, e), tau0 in zip(occ, t_first, strict=True):
        if tau0 == -1:
            continue  # never down while active
        first = tau0 if tau0 >= 0 else a + 1
        if first >= e:
            continue
        span = np.clip(np.minimum(t, e - 1) - first + 1, 0, None)
        x += -(-span // step)  # ceil
    n0 = int(tr.per0_active[0].sum())
    n_on = n0 - np.clip(t - max(config.fire_delay, 1) + 1, 0, n0)
    n_lo = np.maximum(n_on, 1)  # PUR is 0 with nobody onboarded, and min(X, n) / n does not increase with n
    pur = np.minimum(x, n_lo) / n_lo
    pur = np.minimum(pur, config.target_utilization)
    dev = np.maximum(0.0, np.abs(pur - config.target_utilization) - config.utilization_tolerance)
    span_u = max(config.target_utilization, 1.0 - config.target_utilization) - config.utilization_tolerance
    return np.clip(1.0 - dev / span_u, 0.0, 1.0)


def bound_parts(config: ScenarioConfig, seed: int) -> BoundParts:
    """The upper bound on the score of ``seed`` with its components.

    Args:
        config: the scenario.
        seed: the episode seed (as in :func:`wfbench.core.trace`).

    Returns:
        The :class:`BoundParts` of the seed.
    """
    T = config.horizon
    tr = make_trace(config, seed)
    hazard = config.request_schedule.multipliers(T) / config.request_interval  # as wfbench.core.state.make_params
    cum = np.concatenate([[0.0], np.cumsum(hazard[1:])])  # cum[t] = hazard[1] + ... + hazard[t]
    occ = occupancies(config, tr)
    t_first = _first_failures(config, tr, occ, hazard)
    t_star = min((t for t in t_first if t >= 0), default=T)
    wc = _wc_utility_bound(config, tr)
    pur = _pur_utility_bound(config, tr, occ, t_first)
    a = wc * pur  # before t* nobody has worked: pur is u_PUR(0), which is 0 unless the target is below 0.5
    in_s = a > 0.0  # S: the steps where NSW_t can be above 0
    n_s = int(in_s.sum())
    if n_s == 0:
        return BoundParts(0.0, 0.0, t_star, wc, pur, a, 0.0, 0.0)
    per_step = float(np.cbrt(a).sum() / T)
    afd_sum = _downtime_lower_bound(config, tr, occ, cum, t_first, in_s)
    afd_sum = min(afd_sum, float(n_s))
    holder = float(np.sqrt(a).sum() ** (2.0 / 3.0) * (n_s - afd_sum) ** (1.0 / 3.0) / T)
    return BoundParts(min(holder, per_step), per_step, t_star, wc, pur, a, afd_sum, afd_sum / T)


def score_upper_bound(config: ScenarioConfig, seeds: int | Iterable[int]) -> np.ndarray:
    """Per seed, a score that no policy can exceed (``docs/hindsight.md``, "The upper bound").

    Args:
        config: a :class:`ScenarioConfig` (a name is resolved by :func:`wfbench.scenario`).
        seeds: ``n`` for seeds ``0..n-1``, or a sequence of seeds.

    Returns:
        ``(len(seeds),)`` float64: the bound of each seed, in seed order.
    """
    config = require_config(config, "score_upper_bound")
    seeds = range(int(seeds)) if isinstance(seeds, (int, np.integer)) else seeds
    return np.array([bound_parts(config, int(s)).bound for s in seeds], dtype=np.float64)
