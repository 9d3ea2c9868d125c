"""Compiled dispatch rules: nearest-first, inverse-distance, random and the (sparse) optimal assignment.

Part of :mod:`wfbench.policies.kernels`; ``docs/policies.md`` describes the rules.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from wfbench.policies.kernels.common import HP_FIX0, HP_REVISIT, HP_SPEED, HP_UNASSIGNED, SPARSE_K_PEOPLE
from wfbench.solvers.lap import knn_manhattan, lap_min, lap_sparse

from wfbench.core.observe import FAC_X, FAC_Y, PER_LEVEL, PER_X, PER_Y
from wfbench.core.rng import STREAM_POLICY_DISPATCH, uniform


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
def _nobody_sent(O, out, used):
    """Begin a step of the per-request rules: every request to the no-op, nobody used; returns (M, N)."""
    N = O.personnel.shape[1]
    out[:] = N
    used[:] = False
    return O.facilities.shape[1], N


@njit(cache=True, inline="always")
def _free(b, O, used, p):
    """Whether person ``p`` can still be sent this step: dispatchable and not yet picked."""
    return O.dispatchable[b, p] == 1 and not used[p]


@njit(cache=True, inline="always")
def dispatch_inverse_distance(b, O, out, key, t, used, w):
    """For each open request in slot order, sample a free person with probability ~ 1 / (1 + distance).

    ``used`` (N,) bool and ``w`` (N,) float are scratch space.
    """
    M, N = _nobody_sent(O, out, used)
    for f in range(M):
        if O.requesting[b, f] != 1:
            continue
        total = 0.0
        for p in range(N):
            if _free(b, O, used, p):
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
    M, N = _nobody_sent(O, out, used)
    for f in range(M):
        if O.requesting[b, f] != 1:
            continue
        n_free = 0
        for p in range(N):
            if _free(b, O, used, p):
                n_free += 1
        k = int(uniform(key, STREAM_POLICY_DISPATCH, t, f, 1) * (n_free + 1))
        if k == n_free:
            continue  # the no-op
        for p in range(N):
            if _free(b, O, used, p):
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
