"""Compiled decision rules of the built-in policies, one environment ``b`` at a time.

Every kernel reads only the observation (:class:`wfbench.core.observe.Obs`) and its own
policy state, so the same kernel serves ``Policy.act(obs)`` and the compiled whole-
episode rollout (:mod:`wfbench.policies.rollout`), which therefore give identical results.
Randomized kernels draw from :func:`wfbench.core.rng.uniform` with the policy's own key per
environment, indexed by (step, purpose, item): a seed gives the same decisions alone
or inside any batch.

The rules, their codes (the compiled rollout dispatches on them) and the layout of the
hyper-parameter vector are read from the tables of :mod:`wfbench.policies.rules` when this
module is imported: the ``D_``, ``W_`` and ``P_`` constants below are the codes of the
dispatch, workforce and positioning rules there (0: each decision's no-op), and the
``HP_`` constants the positions of the fields of ``hp`` that the kernels read.

Each decision reads its own row of the hyper-parameter matrix ``hp`` (3 x
``len(HP_FIELDS)``: dispatch, workforce, positioning), so two parts of a composite never
share a value by accident.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from wfbench.policies.rules import HYPERPARAMETERS, code
from wfbench.solvers.facility_location import greedy_open, local_search, p_median_sparse
from wfbench.solvers.lap import knn_manhattan, lap_min, lap_sparse
from wfbench.solvers.staffing import sqrt_staffing_servers

from wfbench.core.observe import (
    FAC_DOWNTIME,
    FAC_REQUESTING,
    FAC_X,
    FAC_Y,
    G_PUR,
    PER_HEADING_OUT,
    PER_HOME_X,
    PER_HOME_Y,
    PER_LEVEL,
    PER_X,
    PER_Y,
)
from wfbench.core.rng import STREAM_POLICY_DISPATCH, STREAM_POLICY_POSITIONING, STREAM_POLICY_WORKFORCE, normal, uniform

# the codes of the rules (wfbench.policies.rules.RULES) that the kernels below make
D_NOOP = code("dispatch", "none")
D_NEAREST = code("dispatch", "nearest")
D_INVERSE = code("dispatch", "inverse-distance")  # inverse-distance sampling
D_RANDOM = code("dispatch", "random")
D_ASSIGN = code("dispatch", "assignment")  # optimal assignment (wfbench.solvers.lap.lap_min)
D_ASSIGN_SPARSE = code("dispatch", "assignment-sparse")  # ... on the k nearest (wfbench.solvers.lap.lap_sparse)
W_NOOP = code("workforce", "fixed")
W_THRESHOLD = code("workforce", "threshold")
W_EPSILON = code("workforce", "threshold-epsilon")  # epsilon-greedy threshold
W_RANDOM = code("workforce", "random")
W_STAFFING = code("workforce", "staffing")  # square-root staffing (wfbench.solvers.staffing)
P_NONE = code("positioning", "none")  # zeros
P_SPATIAL = code("positioning", "spatial")  # spatial averaging
P_GAUSSIAN = code("positioning", "spatial-gaussian")  # spatial averaging with Gaussian noise
P_RANDOM = code("positioning", "random")
P_FACILITY = code("positioning", "facility-location")  # p-median (wfbench.solvers.facility_location)
P_FACILITY_SPARSE = code("positioning", "facility-location-sparse")  # ... on the k nearest (p_median_sparse)

# The candidate graphs of the sparse solver rules (docs/solvers.md, "Sparse candidate graphs"): each open
# request considers its SPARSE_K_PEOPLE nearest dispatchable people, each p-median client its SPARSE_K_SITES
# nearest sites, each home its SPARSE_K_MEDIANS nearest medians (Manhattan distance, ties to the lower slot);
# chosen by measurement (benchmarks/sparse_k.py)
SPARSE_K_PEOPLE = 8
SPARSE_K_SITES = 8
SPARSE_K_MEDIANS = 8

# Layout of the hyper-parameter vector ``hp`` (wfbench.policies.rules.HYPERPARAMETERS: meanings and defaults).
HP_FIELDS: tuple[str, ...] = tuple(h.name for h in HYPERPARAMETERS)
HP_DEFAULTS: dict[str, float] = {h.name: h.default for h in HYPERPARAMETERS}
# the position of each field the kernels read
HP_HIGH = HP_FIELDS.index("high")
HP_LOW = HP_FIELDS.index("low")
HP_COOLDOWN = HP_FIELDS.index("cooldown")
HP_WARMUP = HP_FIELDS.index("warmup")
HP_EPS = HP_FIELDS.index("epsilon")
HP_P0 = HP_FIELDS.index("p_novice")
HP_P1 = HP_FIELDS.index("p_mid")
HP_P2 = HP_FIELDS.index("p_expert")
HP_SMOOTH = HP_FIELDS.index("smoothing")
HP_REQW = HP_FIELDS.index("request_weight")
HP_NOISE = HP_FIELDS.index("noise")
HP_SPEED = HP_FIELDS.index("speed")
HP_SERVICE = HP_FIELDS.index("service_time")
HP_FIX0 = HP_FIELDS.index("fix_novice")  # a level's is HP_FIX0 + level: the three follow each other
HP_FIX1 = HP_FIELDS.index("fix_mid")
HP_FIX2 = HP_FIELDS.index("fix_expert")
HP_REVISIT = HP_FIELDS.index("revisit_cost")
HP_UNASSIGNED = HP_FIELDS.index("unassigned_cost")
HP_BETA = HP_FIELDS.index("beta")
HP_HYST = HP_FIELDS.index("hysteresis")
HP_RATE = HP_FIELDS.index("rate_smoothing")
HP_REFRESH = HP_FIELDS.index("refresh")
HP_FLOOR = HP_FIELDS.index("demand_floor")


class PolicyState(NamedTuple):
    """Per-environment memory of the built-in policies."""

    keys: np.ndarray  # (B, 3) uint64 random key per decision (dispatch, workforce, positioning)
    cooldown_until: np.ndarray  # (B,) int64 first step a workforce action may be taken again
    demand: np.ndarray  # (B, M) float64 smoothed rate of new requests per facility slot
    prev_down: np.ndarray  # (B, M) int8 request flag seen at the previous step
    prev_active: np.ndarray  # (B, M) int8 active flag seen at the previous step
    rate: np.ndarray  # (B,) float64 staffing: smoothed number of new requests per step
    rate_prev_down: np.ndarray  # (B, M) int8 staffing: request flag seen at the previous step
    pos_cache: np.ndarray  # (B, 2, M) float64 facility-location: the maps of the last solve
    pos_next: np.ndarray  # (B,) int64 facility-location: step of the next solve
    prev_xy: np.ndarray  # (B, N, 2) float64 staffing: position at the previous step (NaN: not heading out)
    speed_seen: np.ndarray  # (B,) float64 staffing: largest one-step move seen while heading out (0: none yet)
    # scratch space of the dispatch kernels, so that they allocate nothing per step
    req_buf: np.ndarray  # (B, M) int64
    per_buf: np.ndarray  # (B, N) int64
    w_buf: np.ndarray  # (B, N) float64
    used_buf: np.ndarray  # (B, N) bool


def allocate_state(B: int, M: int, N: int) -> PolicyState:
    return PolicyState(
        keys=np.zeros((B, 3), dtype=np.uint64),
        cooldown_until=np.zeros(B, dtype=np.int64),
        demand=np.zeros((B, M), dtype=np.float64),
        prev_down=np.zeros((B, M), dtype=np.int8),
        prev_active=np.zeros((B, M), dtype=np.int8),
        rate=np.zeros(B, dtype=np.float64),
        rate_prev_down=np.zeros((B, M), dtype=np.int8),
        pos_cache=np.zeros((B, 2, M), dtype=np.float64),
        pos_next=np.zeros(B, dtype=np.int64),
        prev_xy=np.full((B, N, 2), np.nan),
        speed_seen=np.zeros(B, dtype=np.float64),
        req_buf=np.zeros((B, M), dtype=np.int64),
        per_buf=np.zeros((B, N), dtype=np.int64),
        w_buf=np.zeros((B, N), dtype=np.float64),
        used_buf=np.zeros((B, N), dtype=np.bool_),
    )


# -- dispatch -----------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _dist_to(O, b, f, x, y):
    """Manhattan distance from the cell (x, y) to facility slot f."""
    return abs(x - O.facilities[b, f, FAC_X]) + abs(y - O.facilities[b, f, FAC_Y])


@njit(cache=True, inline="always")
def _dist(O, b, f, p):
    return (abs(O.personnel[b, p, PER_X] - O.facilities[b, f, FAC_X])
            + abs(O.personnel[b, p, PER_Y] - O.facilities[b, f, FAC_Y]))


@njit(cache=True, inline="always")
def fill_open_requests_and_free_people(b, O, reqs, people):
    """Slots of the open unassigned requests and of the dispatchable people, in slot order.

    They are written into ``reqs`` (M,) and ``people`` (N,); returns their counts.
    """
    nr = 0
    for f in range(O.facilities.shape[1]):
        if O.requesting[b, f] == 1:
            reqs[nr] = f
            nr += 1
    npl = 0
    for p in range(O.personnel.shape[1]):
        if O.dispatchable[b, p] == 1:
            people[npl] = p
            npl += 1
    return nr, npl


@njit(cache=True)
def open_requests_and_free_people(b, O):
    """Slots of the open unassigned requests and of the dispatchable people, in slot order."""
    reqs = np.empty(O.facilities.shape[1], dtype=np.int64)
    people = np.empty(O.personnel.shape[1], dtype=np.int64)
    nr, npl = fill_open_requests_and_free_people(b, O, reqs, people)
    return reqs[:nr], people[:npl]


@njit(cache=True, inline="always")
def _remove_at(a, i, n):
    """Remove item i of the first n of ``a``, keeping the others in order."""
    for k in range(i, n - 1):
        a[k] = a[k + 1]


@njit(cache=True, inline="always")
def dispatch_nearest(b, O, out, reqs, people):
    """Greedy: repeatedly send the closest (dispatchable person, open request) pair.

    Distance is Manhattan from the person's current position. Ties go to the lowest
    facility slot, then the lowest person slot. ``reqs`` (M,) and ``people`` (N,) are
    scratch space.
    """
    out[:] = O.personnel.shape[1]
    nr, npl = fill_open_requests_and_free_people(b, O, reqs, people)
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
        # both lists stay in slot order so that ties stay lowest-slot first
        _remove_at(reqs, bi, nr)
        nr -= 1
        _remove_at(people, bj, npl)
        npl -= 1


@njit(cache=True, inline="always")
def dispatch_inverse_distance(b, O, out, key, t, used, w):
    """For each open request in slot order, sample a free person with probability ~ 1 / (1 + distance).

    ``used`` (N,) bool and ``w`` (N,) float are scratch space.
    """
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    out[:] = N
    used[:] = False
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


@njit(cache=True, inline="always")
def dispatch_random(b, O, out, key, t, used):
    """For each open request in slot order, uniformly one of: no-op or any still-free dispatchable person.

    ``used`` (N,) bool is scratch space.
    """
    M = O.facilities.shape[1]
    N = O.personnel.shape[1]
    out[:] = N
    used[:] = False
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


@njit(cache=True, inline="always")
def revisit_penalty(hp, level):
    """Expected extra downtime of sending this level: ``revisit_cost * (1 - q) / q`` (geometric visits)."""
    q = hp[HP_FIX0 + level]
    return hp[HP_REVISIT] * (1.0 - q) / q


@njit(cache=True)
def assignment_costs(b, O, hp, reqs, people):
    """Cost of sending each free person (column) to each open request (row).

    Travel time (Manhattan distance from the person's current position over ``speed``)
    plus the expected extra downtime of the person's level (:func:`revisit_penalty`).
    """
    C = np.empty((reqs.shape[0], people.shape[0]))
    for i in range(reqs.shape[0]):
        for j in range(people.shape[0]):
            p = people[j]
            C[i, j] = _dist(O, b, reqs[i], p) / hp[HP_SPEED] + revisit_penalty(hp, int(O.personnel[b, p, PER_LEVEL]))
    return C


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def dispatch_assignment(b, O, out, hp):
    """Optimal assignment of the dispatchable people to the open requests (:func:`assignment_costs`).

    With ``unassigned_cost = inf`` (default) as many requests as possible are served,
    like the greedy heuristic, but at the least total cost; a finite value leaves a
    request open when every free person costs more.
    """
    N = O.personnel.shape[1]
    out[:] = N
    reqs, people = open_requests_and_free_people(b, O)
    nr = reqs.shape[0]
    npl = people.shape[0]
    if nr == 0 or npl == 0:
        return
    C0 = assignment_costs(b, O, hp, reqs, people)
    u = hp[HP_UNASSIGNED]
    if u < np.inf:
        # column npl + i is "leave request i open" at cost u
        C = np.full((nr, npl + nr), np.inf)
        C[:, :npl] = C0
        for i in range(nr):
            C[i, npl + i] = u
    elif nr <= npl:
        C = C0
    else:
        C = C0.T.copy()  # rows must be the smaller side: people
    col4row = np.empty(C.shape[0], dtype=np.int64)
    lap_min(C, col4row)
    if u < np.inf or nr <= npl:
        for i in range(nr):
            if col4row[i] < npl:
                out[reqs[i]] = people[col4row[i]]
    else:
        for j in range(npl):
            out[reqs[col4row[j]]] = people[j]


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def dispatch_assignment_sparse(b, O, out, hp):
    """:func:`dispatch_assignment` on a sparse candidate graph: each request's ``SPARSE_K_PEOPLE`` nearest people.

    Same costs (:func:`assignment_costs`) on the candidate edges, plus each request's
    "nobody": at ``unassigned_cost`` when it is finite, else at a cost above any
    assignment's total, so that as many requests as the graph allows are served, at the
    least total cost (:func:`wfbench.solvers.lap.lap_sparse`, exact on the graph). The
    decision equals the dense one's cost whenever a dense optimum uses candidate edges only.
    """
    N = O.personnel.shape[1]
    out[:] = N
    reqs, people = open_requests_and_free_people(b, O)
    nr = reqs.shape[0]
    npl = people.shape[0]
    if nr == 0 or npl == 0:
        return
    k = min(SPARSE_K_PEOPLE, npl)
    qx = np.empty(nr)
    qy = np.empty(nr)
    for i in range(nr):
        qx[i] = O.facilities[b, reqs[i], FAC_X]
        qy[i] = O.facilities[b, reqs[i], FAC_Y]
    px = np.empty(npl)
    py = np.empty(npl)
    for j in range(npl):
        px[j] = O.personnel[b, people[j], PER_X]
        py[j] = O.personnel[b, people[j], PER_Y]
    idx = np.empty((nr, k), dtype=np.int64)
    dd = np.empty((nr, k))
    cnt = knn_manhattan(qx, qy, px, py, k, idx, dd)
    indptr = np.zeros(nr + 1, dtype=np.int64)
    for i in range(nr):
        indptr[i + 1] = indptr[i] + cnt[i]
    indices = np.empty(indptr[nr], dtype=np.int64)
    cost = np.empty(indptr[nr])
    big = 1.0
    for i in range(nr):
        top = 0.0
        for t in range(cnt[i]):
            e = indptr[i] + t
            p = people[idx[i, t]]
            indices[e] = idx[i, t]
            cost[e] = _dist(O, b, reqs[i], p) / hp[HP_SPEED] + revisit_penalty(hp, int(O.personnel[b, p, PER_LEVEL]))
            top = max(top, cost[e])
        big += top
    u = hp[HP_UNASSIGNED]
    nobody = np.full(nr, u if u < np.inf else big)
    col4row = np.empty(nr, dtype=np.int64)
    lap_sparse(npl, indptr, indices, cost, nobody, col4row)
    for i in range(nr):
        if col4row[i] >= 0:
            out[reqs[i]] = people[col4row[i]]


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


@njit(cache=True, inline="always")
def _retained_homes(b, O, hx, hy):
    """Homes of the people employed and not under notice (onboarding included); their count."""
    h = 0
    for p in range(O.personnel.shape[1]):
        if O.personnel_mask[b, p] == 1 and O.under_notice[b, p] == 0:
            hx[h] = O.personnel[b, p, PER_HOME_X]
            hy[h] = O.personnel[b, p, PER_HOME_Y]
            h += 1
    return h


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
    h = _retained_homes(b, O, hx, hy)
    travel = 0.0
    na = 0
    for f in range(M):
        if O.facility_mask[b, f] == 1 and h > 0:
            best = np.inf
            for k in range(h):
                d = _dist_to(O, b, f, hx[k], hy[k])
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


# -- positioning --------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def observe_history(b, O, S, hp):
    """Update each facility's smoothed request rate from the request flags it shows."""
    M = O.facilities.shape[1]
    a = hp[HP_SMOOTH]
    for f in range(M):
        act = O.facility_mask[b, f]
        down = np.int8(1) if O.facilities[b, f, FAC_REQUESTING] > 0.5 else np.int8(0)
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
    observe_history(b, O, S, hp)
    spatial_weights(b, O, S, hp, out, key, t, noise)


@njit(cache=True, inline="always")
def spatial_weights(b, O, S, hp, out, key, t, noise):
    """The two rows of :func:`positioning_spatial` from the demand history as it stands."""
    M = O.facilities.shape[1]
    max_r = 0.0
    max_d = 0.0
    for f in range(M):
        if O.facility_mask[b, f] == 1:
            max_r = max(max_r, S.demand[b, f])
            max_d = max(max_d, O.facilities[b, f, FAC_DOWNTIME])
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
            d += (1.0 - wr) * O.facilities[b, f, FAC_DOWNTIME] / max_d
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


@njit(cache=True, inline="always")
def _first_unmatched(col4row, med):
    """The first median no home was matched to (``col4row[r]``: home r's median, -1 for "nobody"), or -1."""
    taken = np.zeros(med.shape[0], dtype=np.bool_)
    for r in range(col4row.shape[0]):
        if col4row[r] >= 0:
            taken[col4row[r]] = True
    for c in range(med.shape[0]):
        if not taken[c]:
            return med[c]
    return -1


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def _facility_clients(b, O, S, hp, out, t):
    """What both facility-location rules start from: the refresh, the open sites and each site's client weight.

    Updates the demand history; between refreshes it copies the cached maps into ``out``
    and returns ``ns = -1``, and with no open facility it caches the zero maps and returns
    ``ns = 0``: in both cases ``out`` is final. Otherwise ``out`` is zeroed and it returns
    the open sites (``sites[:ns]``) and their weights ``w``: the floor plus the demand and
    downtime shares, each relative to its largest value.
    """
    M = O.facilities.shape[1]
    observe_history(b, O, S, hp)
    sites = np.empty(M, dtype=np.int64)
    if t < S.pos_next[b]:
        out[:, :] = S.pos_cache[b]
        return sites, -1, np.empty(0)
    S.pos_next[b] = t + max(1, int(hp[HP_REFRESH]))
    out[:, :] = 0.0
    ns = 0
    max_r = 0.0
    max_d = 0.0
    for f in range(M):
        if O.facility_mask[b, f] == 1:
            sites[ns] = f
            ns += 1
            max_r = max(max_r, S.demand[b, f])
            max_d = max(max_d, O.facilities[b, f, FAC_DOWNTIME])
    if ns == 0:
        S.pos_cache[b] = out
        return sites, 0, np.empty(0)
    w = np.empty(ns)
    wr = hp[HP_REQW]
    for k in range(ns):
        f = sites[k]
        d = hp[HP_FLOOR]
        if max_r > 0.0:
            d += wr * S.demand[b, f] / max_r
        if max_d > 0.0:
            d += (1.0 - wr) * O.facilities[b, f, FAC_DOWNTIME] / max_d
        w[k] = d
    return sites, ns, w


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def positioning_facility(b, O, S, hp, out, t):
    """p-median positioning: hire where the demand's p-median lacks a person, let go the cheapest loss.

    Clients are the active facilities, weighted by ``demand_floor`` plus the spatial
    heuristic's demand (smoothed request rate and rolling downtime); candidate sites are
    the active facilities. Every ``refresh`` steps: solve the p-median with
    ``p = retained headcount + 1`` (greedy + swap local search,
    :mod:`wfbench.solvers.facility_location`), match the medians to the current homes by an
    optimal assignment on distance, and put the hire map's weight on the median left
    unmatched (the site the workforce lacks). The let-go map gives the facility nearest
    each home a weight that falls with the increase in p-median cost that person's
    removal causes (1 for the cheapest removal). The simulator picks within the level
    through its heat map (sigma = heat_sigma), so the let-go choice is approximate when
    homes of one level sit close together.
    """
    N = O.personnel.shape[1]
    sites, ns, w = _facility_clients(b, O, S, hp, out, t)
    if ns <= 0:
        return
    # weighted site-to-site distances: C[candidate, client]
    C = np.empty((ns, ns))
    for i in range(ns):
        for j in range(ns):
            fi = sites[i]
            fj = sites[j]
            C[i, j] = w[j] * _dist_to(O, b, fj, O.facilities[b, fi, FAC_X], O.facilities[b, fi, FAC_Y])
    hx = np.empty(N)
    hy = np.empty(N)
    h = _retained_homes(b, O, hx, hy)
    # hire map
    p_med = min(h + 1, ns)
    zero = np.zeros(ns)
    is_open = greedy_open(C, zero, p_med)
    local_search(C, zero, is_open, p_med, 1000, 1e-9)
    med = np.empty(p_med, dtype=np.int64)
    k = 0
    for i in range(ns):
        if is_open[i]:
            med[k] = i
            k += 1
    hire = -1
    if p_med > h:
        if h == 0:
            hire = med[0]
        else:
            # rows = homes (h < p_med), columns = medians: the unmatched median is the hire site
            D = np.empty((h, p_med))
            for r in range(h):
                for c in range(p_med):
                    f = sites[med[c]]
                    D[r, c] = _dist_to(O, b, f, hx[r], hy[r])
            col4row = np.empty(h, dtype=np.int64)
            lap_min(D, col4row)
            hire = _first_unmatched(col4row, med)
    else:
        # every site already has someone: the site whose demand is farthest from any home
        best = -1.0
        for j in range(ns):
            f = sites[j]
            near = np.inf
            for r in range(h):
                near = min(near, _dist_to(O, b, f, hx[r], hy[r]))
            if w[j] * near > best:
                best = w[j] * near
                hire = j
    out[0, sites[hire]] = 1.0
    # let-go map: removal cost of each retained person (clients move to their second nearest home)
    if h >= 2:
        delta = np.zeros(h)
        for j in range(ns):
            f = sites[j]
            d1 = np.inf
            d2 = np.inf
            a1 = -1
            for r in range(h):
                d = _dist_to(O, b, f, hx[r], hy[r])
                if d < d1:
                    d2 = d1
                    d1 = d
                    a1 = r
                elif d < d2:
                    d2 = d
            delta[a1] += w[j] * (d2 - d1)
        lo = delta.min()
        hi = delta.max()
        for r in range(h):
            near = -1
            best = np.inf
            for j in range(ns):
                f = sites[j]
                d = _dist_to(O, b, f, hx[r], hy[r])
                if d < best:
                    best = d
                    near = f
            v = 1.0 if hi <= lo else 1.0 - (delta[r] - lo) / (hi - lo)
            out[1, near] = max(out[1, near], v * v)
    S.pos_cache[b] = out


@njit(cache=True, _nrt=True)  # allocates; called from code compiled without the runtime
def positioning_facility_sparse(b, O, S, hp, out, t):
    """:func:`positioning_facility` with its two solves on sparse candidate graphs.

    The same clients, weights, refresh, p and maps; only two steps differ. The p-median
    is solved on each client's ``SPARSE_K_SITES`` nearest sites
    (:func:`wfbench.solvers.facility_location.p_median_sparse`: lazy greedy and swap search on the
    lists, a client outside them priced at its distance to its next-nearest site), and the
    homes are matched to the medians on each home's ``SPARSE_K_MEDIANS`` nearest medians
    (:func:`wfbench.solvers.lap.lap_sparse`, with a "nobody" per home above any
    matching's cost; the hire site is the first median left unmatched, as in the dense
    rule). The nearest-home and second-nearest-home scans of the other steps are k-nearest
    queries on a grid that return exactly what the dense scans find, so the let-go map
    is the dense rule's.
    """
    N = O.personnel.shape[1]
    sites, ns, w = _facility_clients(b, O, S, hp, out, t)
    if ns <= 0:
        return
    sx = np.empty(ns)
    sy = np.empty(ns)
    for k in range(ns):
        sx[k] = O.facilities[b, sites[k], FAC_X]
        sy[k] = O.facilities[b, sites[k], FAC_Y]
    # each client's nearest sites; the (k+1)-th prices the sites outside its list
    ks = min(SPARSE_K_SITES + 1, ns)
    cand = np.empty((ns, ks), dtype=np.int64)
    cd = np.empty((ns, ks))
    knn_manhattan(sx, sy, sx, sy, ks, cand, cd)
    kc = min(SPARSE_K_SITES, ns)
    far = np.full(ns, np.inf)
    ccost = np.empty((ns, kc))
    count = np.full(ns, kc, dtype=np.int64)
    for j in range(ns):
        for q in range(kc):
            ccost[j, q] = w[j] * cd[j, q]
        if ks > kc:
            far[j] = w[j] * cd[j, kc]
    hx = np.empty(N)
    hy = np.empty(N)
    h = _retained_homes(b, O, hx, hy)
    # hire map
    p_med = min(h + 1, ns)
    is_open, _ = p_median_sparse(ns, cand[:, :kc].copy(), ccost, count, far, p_med, 1000, 1e-9)
    med = np.empty(p_med, dtype=np.int64)
    k = 0
    for i in range(ns):
        if is_open[i]:
            med[k] = i
            k += 1
    hire = -1
    # each site's two nearest homes (the let-go map; the nearest alone for the hire site below)
    kh = min(2, h)
    hn = np.empty((ns, max(kh, 1)), dtype=np.int64)
    hd = np.empty((ns, max(kh, 1)))
    if h > 0:
        knn_manhattan(sx, sy, hx[:h], hy[:h], kh, hn, hd)
    if p_med > h:
        if h == 0:
            hire = med[0]
        else:
            # rows = homes (h < p_med), columns = medians: the first median left unmatched is the hire site
            mx = np.empty(p_med)
            my = np.empty(p_med)
            for c in range(p_med):
                mx[c] = sx[med[c]]
                my[c] = sy[med[c]]
            km = min(SPARSE_K_MEDIANS, p_med)
            mi = np.empty((h, km), dtype=np.int64)
            md = np.empty((h, km))
            knn_manhattan(hx[:h], hy[:h], mx, my, km, mi, md)
            indptr = np.arange(h + 1, dtype=np.int64) * km
            big = 1.0
            for r in range(h):
                big += md[r, km - 1]
            col4row = np.empty(h, dtype=np.int64)
            lap_sparse(p_med, indptr, mi.ravel(), md.ravel(), np.full(h, big), col4row)
            hire = _first_unmatched(col4row, med)
    else:
        # every site already has someone: the site whose demand is farthest from any home
        best = -1.0
        for j in range(ns):
            near = hd[j, 0] if h > 0 else np.inf
            if w[j] * near > best:
                best = w[j] * near
                hire = j
    out[0, sites[hire]] = 1.0
    # let-go map: removal cost of each retained person (clients move to their second nearest home)
    if h >= 2:
        delta = np.zeros(h)
        for j in range(ns):
            delta[hn[j, 0]] += w[j] * (hd[j, 1] - hd[j, 0])
        lo = delta.min()
        hi = delta.max()
        ni = np.empty((h, 1), dtype=np.int64)
        nd = np.empty((h, 1))
        knn_manhattan(hx[:h], hy[:h], sx, sy, 1, ni, nd)
        for r in range(h):
            near = sites[ni[r, 0]]
            v = 1.0 if hi <= lo else 1.0 - (delta[r] - lo) / (hi - lo)
            out[1, near] = max(out[1, near], v * v)
    S.pos_cache[b] = out


# -- one environment, all three decisions --------------------------------------------------------
@njit(cache=True, inline="always")
def act_env(b, O, S, codes, hp, dispatch, workforce, positioning, t, lazy):
    """Fill the three decisions of environment b for the given codes (``hp`` has a row per decision).

    ``lazy`` (the compiled rollout, where all three decisions are built in) skips the
    spatial positioning weights on steps whose workforce action is the no-op: the step
    does not read them then, and the demand history they come from is still updated, so
    the episode is the same. ``Policy.act`` always fills them (another agent may hire).

    Callers compile this without numba's runtime (see ``wfbench.core.dynamics.step_env``): the
    heuristic and random kernels work in the scratch arrays of the policy state, and the
    solver kernels, which allocate, are compiled with ``_nrt=True`` set explicitly.
    """
    dc = codes[0]
    if dc == D_NEAREST:
        dispatch_nearest(b, O, dispatch[b], S.req_buf[b], S.per_buf[b])
    elif dc == D_INVERSE:
        dispatch_inverse_distance(b, O, dispatch[b], S.keys[b, 0], t, S.used_buf[b], S.w_buf[b])
    elif dc == D_RANDOM:
        dispatch_random(b, O, dispatch[b], S.keys[b, 0], t, S.used_buf[b])
    elif dc == D_ASSIGN:
        dispatch_assignment(b, O, dispatch[b], hp[0])
    elif dc == D_ASSIGN_SPARSE:
        dispatch_assignment_sparse(b, O, dispatch[b], hp[0])
    else:
        dispatch[b, :] = O.personnel.shape[1]
    wc = codes[1]
    hw = hp[1]
    if wc == W_THRESHOLD:
        workforce[b] = workforce_threshold(b, O, S, hw, S.keys[b, 1], t, 0.0)
    elif wc == W_EPSILON:
        workforce[b] = workforce_threshold(b, O, S, hw, S.keys[b, 1], t, hw[HP_EPS])
    elif wc == W_RANDOM:
        workforce[b] = workforce_random(b, O, S.keys[b, 1], t)
    elif wc == W_STAFFING:
        workforce[b] = workforce_staffing(b, O, S, hw, S.keys[b, 1], t)
    else:
        workforce[b] = 0
    pc = codes[2]
    hpp = hp[2]
    if pc == P_SPATIAL or pc == P_GAUSSIAN:
        if lazy and workforce[b] == 0:
            observe_history(b, O, S, hpp)
        else:
            noise = hpp[HP_NOISE] if pc == P_GAUSSIAN else 0.0
            positioning_spatial(b, O, S, hpp, positioning[b], S.keys[b, 2], t, noise)
    elif pc == P_RANDOM:
        positioning_random(b, O, positioning[b], S.keys[b, 2], t)
    elif pc == P_FACILITY:
        positioning_facility(b, O, S, hpp, positioning[b], t)
    elif pc == P_FACILITY_SPARSE:
        positioning_facility_sparse(b, O, S, hpp, positioning[b], t)
    else:
        positioning[b, :, :] = 0.0


@njit(cache=True, _nrt=False)  # see act_env
def act_batch(O, S, codes, hp, dispatch, workforce, positioning, t):
    for b in range(O.facilities.shape[0]):
        act_env(b, O, S, codes, hp, dispatch, workforce, positioning, t[b], False)
