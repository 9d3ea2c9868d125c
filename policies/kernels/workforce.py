"""Compiled workforce rules: the (epsilon-greedy) threshold, random and square-root staffing.

Part of :mod:`wfbench.policies.kernels`; ``docs/policies.md`` describes the rules.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from wfbench.policies.kernels.common import (
    HP_BETA,
    HP_COOLDOWN,
    HP_FIX0,
    HP_FIX1,
    HP_FIX2,
    HP_HIGH,
    HP_HYST,
    HP_LOW,
    HP_P0,
    HP_P1,
    HP_P2,
    HP_RATE,
    HP_SERVICE,
    HP_SPEED,
    HP_WARMUP,
    dist_to,
    retained_homes,
)
from wfbench.solvers.staffing import sqrt_staffing_servers

from wfbench.core.observe import FAC_REQUESTING, G_PUR, PER_HEADING_OUT, PER_LEVEL, PER_X, PER_Y
from wfbench.core.rng import STREAM_POLICY_WORKFORCE, uniform


@njit(cache=True, inline="always")
def _draw_level(u, hp, m0, m1, m2):
    """A level from (p_novice, p_mid, p_expert), restricted to the levels with flag 1."""
    w0 = hp[HP_P0] * m0
    w1 = hp[HP_P1] * m1
    w2 = hp[HP_P2] * m2
    total = w0 + w1 + w2
    if total <= 0.0:
        return -1
    x = u * total
    if x < w0:
        return 0
    if x < w0 + w1:
        return 1
    return 2


@njit(cache=True, inline="always")
def _workforce_action(b, O, S, hp, decision, u, t):
    """The action for a decision (0 nothing, 1 hire, 2 let go) with the level drawn by ``u``; starts the cooldown."""
    m = O.workforce_mask[b]
    action = 0
    if decision == 1:
        lv = _draw_level(u, hp, m[1], m[2], m[3])
        if lv >= 0:
            action = 1 + lv
    elif decision == 2:
        lv = _draw_level(u, hp, m[4], m[5], m[6])
        if lv >= 0:
            action = 4 + lv
    if action != 0:
        S.cooldown_until[b] = t + int(hp[HP_COOLDOWN])
    return action


@njit(cache=True, inline="always")
def workforce_threshold(b, O, S, hp, key, t, epsilon):
    """Hire when the rolling utilization is above ``high``, let go when below ``low``.

    At most one action per ``cooldown`` steps, none before ``warmup``. With
    ``epsilon > 0`` (the epsilon-greedy variant) each eligible step replaces the
    threshold decision by a uniformly random one of (hire, let go, nothing) with
    probability epsilon. Levels are drawn from (p_novice, p_mid, p_expert).
    """
    if t < hp[HP_WARMUP] or t < S.cooldown_until[b]:
        return 0
    pur = O.globals[b, G_PUR]
    decision = 0
    if pur > hp[HP_HIGH]:
        decision = 1
    elif pur < hp[HP_LOW]:
        decision = 2
    if epsilon > 0.0 and uniform(key, STREAM_POLICY_WORKFORCE, t, 0, 0) < epsilon:
        decision = int(uniform(key, STREAM_POLICY_WORKFORCE, t, 1, 0) * 3.0)
    return _workforce_action(b, O, S, hp, decision, uniform(key, STREAM_POLICY_WORKFORCE, t, 2, 0), t)


@njit(cache=True)
def workforce_random(b, O, key, t):
    """Uniformly one of the valid workforce actions (no-op included)."""
    m = O.workforce_mask[b]
    n = 0
    for a in range(m.shape[0]):
        n += m[a]
    k = int(uniform(key, STREAM_POLICY_WORKFORCE, t, 3, 0) * n)
    for a in range(m.shape[0]):
        if m[a] == 1:
            if k == 0:
                return a
            k -= 1
    return 0


@njit(cache=True)
def staffing_target(b, O, S, hp):
    """The square-root-staffing headcount for environment b and the offered load behind it.

    Offered load ``R = lambda * E[S]``: ``lambda`` is the smoothed number of new requests
    per step; ``E[S] = (2 * travel + service_time) / q`` with ``travel`` the mean distance
    from each active facility to its nearest retained home over ``speed`` (what a
    nearest-first dispatcher travels) and ``q`` the fix probability averaged over the
    workforce's levels. Target ``c = ceil(R + beta * sqrt(R))``, at least 1.
    """
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    hx = np.empty(N)
    hy = np.empty(N)
    h = retained_homes(b, O, hx, hy)
    travel = 0.0
    na = 0
    for f in range(M):
        if O.facility_mask[b, f] == 1 and h > 0:
            best = np.inf
            for k in range(h):
                d = dist_to(O, b, f, hx[k], hy[k])
                best = min(best, d)
            travel += best
            na += 1
    if na > 0:
        travel /= na
    travel /= S.speed_seen[b] if S.speed_seen[b] > 0.0 else hp[HP_SPEED]
    qsum = 0.0
    n = 0
    for p in range(N):
        if O.personnel_mask[b, p] == 1 and O.under_notice[b, p] == 0:
            qsum += hp[HP_FIX0 + int(O.personnel[b, p, PER_LEVEL])]
            n += 1
    if n > 0:
        q = qsum / n
    else:
        q = (hp[HP_P0] * hp[HP_FIX0] + hp[HP_P1] * hp[HP_FIX1] + hp[HP_P2] * hp[HP_FIX2]) / (
            hp[HP_P0] + hp[HP_P1] + hp[HP_P2])
    R = S.rate[b] * (2.0 * travel + hp[HP_SERVICE]) / q
    return max(1, sqrt_staffing_servers(R, hp[HP_BETA])), h, R


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def workforce_staffing(b, O, S, hp, key, t):
    """Hire or let go toward the square-root-staffing headcount (:func:`staffing_target`).

    The request rate is learned every step (a running mean, then an exponential
    average with weight ``rate_smoothing``). After ``warmup`` and at most once per
    ``cooldown``: hire when the retained headcount is below the target, let go when it
    exceeds the target by more than ``hysteresis``. Levels are drawn like the threshold
    heuristic's, so the comparison isolates the headcount rule.
    """
    M = O.facilities.shape[1]
    onsets = 0.0
    for f in range(M):
        down = np.int8(1) if (O.facility_mask[b, f] == 1 and O.facilities[b, f, FAC_REQUESTING] > 0.5) else np.int8(0)
        if down == 1 and S.rate_prev_down[b, f] == 0:
            onsets += 1.0
        S.rate_prev_down[b, f] = down
    a = max(1.0 / (t + 1.0), hp[HP_RATE])
    S.rate[b] = (1.0 - a) * S.rate[b] + a * onsets
    # learn the travel speed from people heading out (the ``speed`` parameter is only the prior)
    for p in range(O.personnel.shape[1]):
        if O.personnel_mask[b, p] == 1 and O.personnel[b, p, PER_HEADING_OUT] > 0.5:
            x = O.personnel[b, p, PER_X]
            y = O.personnel[b, p, PER_Y]
            if S.prev_xy[b, p, 0] == S.prev_xy[b, p, 0]:  # not NaN: was heading out last step too
                S.speed_seen[b] = max(S.speed_seen[b], abs(x - S.prev_xy[b, p, 0]) + abs(y - S.prev_xy[b, p, 1]))
            S.prev_xy[b, p, 0] = x
            S.prev_xy[b, p, 1] = y
        else:
            S.prev_xy[b, p, 0] = np.nan
    if t < hp[HP_WARMUP] or t < S.cooldown_until[b]:
        return 0
    target, h, R = staffing_target(b, O, S, hp)
    decision = 1 if h < target else (2 if h > target + hp[HP_HYST] else 0)
    return _workforce_action(b, O, S, hp, decision, uniform(key, STREAM_POLICY_WORKFORCE, t, 4, 0), t)
