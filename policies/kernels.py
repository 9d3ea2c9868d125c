"""Compiled decision rules of the built-in policies, one environment ``b`` at a time.

Every kernel reads only the observation (:class:`wfbench.observe.Obs`) and its own
policy state, so the same kernel serves ``Policy.act(obs)`` and the compiled whole-
episode rollout (:mod:`policies.rollout`), which therefore give identical results.
Randomized kernels draw from :func:`wfbench.rng.uniform` with the policy's own key per
environment, indexed by (step, purpose, item): a seed gives the same decisions alone
or inside any batch.

Codes (the compiled rollout dispatches on them):

- dispatch: 0 no-op, 1 nearest, 2 inverse-distance sampling, 3 random;
- workforce: 0 no-op, 1 threshold, 2 epsilon-greedy threshold, 3 random;
- positioning: 0 none (zeros), 1 spatial averaging, 2 spatial averaging with Gaussian
  noise, 3 random.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from wfbench.observe import G_PUR
from wfbench.rng import STREAM_POLICY_DISPATCH, STREAM_POLICY_POSITIONING, STREAM_POLICY_WORKFORCE, normal, uniform

D_NOOP, D_NEAREST, D_INVERSE, D_RANDOM = 0, 1, 2, 3
W_NOOP, W_THRESHOLD, W_EPSILON, W_RANDOM = 0, 1, 2, 3
P_NONE, P_SPATIAL, P_GAUSSIAN, P_RANDOM = 0, 1, 2, 3

# Layout of the hyper-parameter vector ``hp``.
HP_FIELDS = (
    "high",  # threshold workforce: hire when utilization is above this
    "low",  # ... let go when below this
    "cooldown",  # steps between two workforce actions
    "warmup",  # no workforce action before this step
    "epsilon",  # epsilon-greedy: probability of a random decision per step after the cooldown
    "p_novice",  # level draw of a hire (and of a let-go among the levels present)
    "p_mid",
    "p_expert",
    "smoothing",  # spatial positioning: weight of a new request in the exponential average
    "request_weight",  # ... share of the request history in a facility's demand (the rest: downtime)
    "noise",  # Gaussian variant: standard deviation of the log-normal noise on the demand
)
HP_DEFAULTS = {
    "high": 0.8,
    "low": 0.45,
    "cooldown": 30.0,
    "warmup": 50.0,
    "epsilon": 0.02,
    "p_novice": 0.25,
    "p_mid": 0.5,
    "p_expert": 0.25,
    "smoothing": 0.01,
    "request_weight": 0.5,
    "noise": 0.5,
}
(HP_HIGH, HP_LOW, HP_COOLDOWN, HP_WARMUP, HP_EPS, HP_P0, HP_P1, HP_P2, HP_SMOOTH, HP_REQW, HP_NOISE) = range(len(HP_FIELDS))


class PolicyState(NamedTuple):
    """Per-environment memory of the built-in policies."""

    keys: np.ndarray  # (B, 3) uint64 random key per decision (dispatch, workforce, positioning)
    cooldown_until: np.ndarray  # (B,) int64 first step a workforce action may be taken again
    demand: np.ndarray  # (B, M) float64 smoothed rate of new requests per facility slot
    prev_down: np.ndarray  # (B, M) int8 request flag seen at the previous step
    prev_active: np.ndarray  # (B, M) int8 active flag seen at the previous step


def allocate_state(B: int, M: int) -> PolicyState:
    return PolicyState(
        keys=np.zeros((B, 3), dtype=np.uint64),
        cooldown_until=np.zeros(B, dtype=np.int64),
        demand=np.zeros((B, M), dtype=np.float64),
        prev_down=np.zeros((B, M), dtype=np.int8),
        prev_active=np.zeros((B, M), dtype=np.int8),
    )


# -- dispatch -----------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _dist(O, b, f, p):
    return abs(O.personnel[b, p, 2] - O.facilities[b, f, 0]) + abs(O.personnel[b, p, 3] - O.facilities[b, f, 1])


@njit(cache=True, inline="always")
def dispatch_nearest(b, O, out):
    """Greedy: repeatedly send the closest (dispatchable person, open request) pair.

    Distance is Manhattan from the person's current position. Ties go to the lowest
    facility slot, then the lowest person slot.
    """
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    out[:] = N
    reqs = np.empty(M, dtype=np.int64)
    nr = 0
    for f in range(M):
        if O.requesting[b, f] == 1:
            reqs[nr] = f
            nr += 1
    if nr == 0:
        return
    people = np.empty(N, dtype=np.int64)
    npl = 0
    for p in range(N):
        if O.dispatchable[b, p] == 1:
            people[npl] = p
            npl += 1
    while nr > 0 and npl > 0:
        best = np.inf
        bi = -1
        bj = -1
        for i in range(nr):
            for j in range(npl):
                d = _dist(O, b, reqs[i], people[j])
                if d < best:
                    best = d
                    bi = i
                    bj = j
        out[reqs[bi]] = people[bj]
        reqs[bi] = reqs[nr - 1]
        nr -= 1
        people[bj] = people[npl - 1]
        npl -= 1
        # keep both lists in slot order so that ties stay lowest-slot first
        reqs[:nr].sort()
        people[:npl].sort()


@njit(cache=True)
def dispatch_inverse_distance(b, O, out, key, t):
    """For each open request in slot order, sample a free person with probability ~ 1 / (1 + distance)."""
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    out[:] = N
    used = np.zeros(N, dtype=np.bool_)
    w = np.empty(N)
    for f in range(M):
        if O.requesting[b, f] != 1:
            continue
        total = 0.0
        for p in range(N):
            if O.dispatchable[b, p] == 1 and not used[p]:
                w[p] = 1.0 / (1.0 + _dist(O, b, f, p))
                total += w[p]
            else:
                w[p] = 0.0
        if total <= 0.0:
            break
        u = uniform(key, STREAM_POLICY_DISPATCH, t, f, 0) * total
        acc = 0.0
        pick = -1
        for p in range(N):
            if w[p] > 0.0:
                acc += w[p]
                pick = p
                if acc > u:
                    break
        out[f] = pick
        used[pick] = True


@njit(cache=True)
def dispatch_random(b, O, out, key, t):
    """For each open request in slot order, uniformly one of: no-op or any still-free dispatchable person."""
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    out[:] = N
    used = np.zeros(N, dtype=np.bool_)
    for f in range(M):
        if O.requesting[b, f] != 1:
            continue
        n_free = 0
        for p in range(N):
            if O.dispatchable[b, p] == 1 and not used[p]:
                n_free += 1
        k = int(uniform(key, STREAM_POLICY_DISPATCH, t, f, 1) * (n_free + 1))
        if k == n_free:
            continue  # the no-op
        for p in range(N):
            if O.dispatchable[b, p] == 1 and not used[p]:
                if k == 0:
                    out[f] = p
                    used[p] = True
                    break
                k -= 1


# -- workforce ----------------------------------------------------------------------------------
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
    m = O.workforce_mask[b]
    u = uniform(key, STREAM_POLICY_WORKFORCE, t, 2, 0)
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


# -- positioning --------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def observe_history(b, O, S, hp):
    """Update each facility's smoothed request rate from the request flags it shows."""
    M = O.facilities.shape[1]
    a = hp[HP_SMOOTH]
    for f in range(M):
        act = O.facility_mask[b, f]
        down = np.int8(1) if O.facilities[b, f, 3] > 0.5 else np.int8(0)
        if act == 1:
            if S.prev_active[b, f] == 0:
                S.demand[b, f] = 0.0  # a new facility in this slot: forget the old one
                S.prev_down[b, f] = 0
            new = 1.0 if (down == 1 and S.prev_down[b, f] == 0) else 0.0
            S.demand[b, f] = (1.0 - a) * S.demand[b, f] + a * new
        else:
            S.demand[b, f] = 0.0
        S.prev_down[b, f] = down
        S.prev_active[b, f] = act


@njit(cache=True, inline="always")
def positioning_spatial(b, O, S, hp, out, key, t, noise):
    """Spatial averaging: weight each facility by its service demand.

    Demand mixes the smoothed request rate and the rolling downtime, each scaled by its
    maximum over the active facilities. Row 0 (where to hire) is the demand, row 1
    (whom to let go) its complement, so hires go where service is needed and let-gos
    come from where it is not. ``noise > 0`` multiplies the demand by
    ``exp(noise * N(0, 1))`` per facility (the Gaussian-sampling variant).
    """
    M = O.facilities.shape[1]
    observe_history(b, O, S, hp)
    max_r = 0.0
    max_d = 0.0
    for f in range(M):
        if O.facility_mask[b, f] == 1:
            max_r = max(max_r, S.demand[b, f])
            max_d = max(max_d, O.facilities[b, f, 6])
    wr = hp[HP_REQW]
    top = 0.0
    for f in range(M):
        out[0, f] = 0.0
        out[1, f] = 0.0
        if O.facility_mask[b, f] != 1:
            continue
        d = 0.0
        if max_r > 0.0:
            d += wr * S.demand[b, f] / max_r
        if max_d > 0.0:
            d += (1.0 - wr) * O.facilities[b, f, 6] / max_d
        if noise > 0.0:
            d *= np.exp(noise * normal(key, STREAM_POLICY_POSITIONING, t, f, 0))
        out[0, f] = d
        top = max(top, d)
    for f in range(M):
        if O.facility_mask[b, f] == 1:
            out[0, f] = out[0, f] / top if top > 0.0 else 1.0
            out[1, f] = 1.0 - out[0, f]


@njit(cache=True)
def positioning_random(b, O, out, key, t):
    M = O.facilities.shape[1]
    for f in range(M):
        out[0, f] = uniform(key, STREAM_POLICY_POSITIONING, t, f, 1)
        out[1, f] = uniform(key, STREAM_POLICY_POSITIONING, t, f, 2)


# -- one environment, all three decisions --------------------------------------------------------
@njit(cache=True, inline="always")
def act_env(b, O, S, codes, hp, dispatch, workforce, positioning, t):
    """Fill the three decisions of environment b for the given codes."""
    dc = codes[0]
    if dc == D_NEAREST:
        dispatch_nearest(b, O, dispatch[b])
    elif dc == D_INVERSE:
        dispatch_inverse_distance(b, O, dispatch[b], S.keys[b, 0], t)
    elif dc == D_RANDOM:
        dispatch_random(b, O, dispatch[b], S.keys[b, 0], t)
    else:
        dispatch[b, :] = O.personnel.shape[1]
    wc = codes[1]
    if wc == W_THRESHOLD:
        workforce[b] = workforce_threshold(b, O, S, hp, S.keys[b, 1], t, 0.0)
    elif wc == W_EPSILON:
        workforce[b] = workforce_threshold(b, O, S, hp, S.keys[b, 1], t, hp[HP_EPS])
    elif wc == W_RANDOM:
        workforce[b] = workforce_random(b, O, S.keys[b, 1], t)
    else:
        workforce[b] = 0
    pc = codes[2]
    if pc == P_SPATIAL:
        positioning_spatial(b, O, S, hp, positioning[b], S.keys[b, 2], t, 0.0)
    elif pc == P_GAUSSIAN:
        positioning_spatial(b, O, S, hp, positioning[b], S.keys[b, 2], t, hp[HP_NOISE])
    elif pc == P_RANDOM:
        positioning_random(b, O, positioning[b], S.keys[b, 2], t)
    else:
        positioning[b, :, :] = 0.0


@njit(cache=True)
def act_batch(O, S, codes, hp, dispatch, workforce, positioning, t):
    for b in range(O.facilities.shape[0]):
        act_env(b, O, S, codes, hp, dispatch, workforce, positioning, t[b])
