"""Compiled positioning rules: spatial averaging (with noise), random and the (sparse) p-median.

Part of :mod:`wfbench.policies.kernels`; ``docs/policies.md`` describes the rules.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from wfbench.policies.kernels.common import (
    HP_FLOOR,
    HP_REFRESH,
    HP_REQW,
    HP_SMOOTH,
    SPARSE_K_MEDIANS,
    SPARSE_K_SITES,
    dist_to,
    retained_homes,
)
from wfbench.solvers.facility_location import greedy_open, local_search, p_median_sparse
from wfbench.solvers.lap import knn_manhattan, lap_min, lap_sparse

from wfbench.core.observe import FAC_DOWNTIME, FAC_REQUESTING, FAC_X, FAC_Y
from wfbench.core.rng import STREAM_POLICY_POSITIONING, normal, uniform


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
def _medians(is_open, ns, p_med):
    """The p-median's medians: the indices of the ``p_med`` open sites among ``ns``, in order."""
    med = np.empty(p_med, dtype=np.int64)
    k = 0
    for i in range(ns):
        if is_open[i]:
            med[k] = i
            k += 1
    return med


@njit(cache=True, inline="always")
def _farthest_site(w, to_home):
    """The hire site when every site has someone: the largest ``w[j] * to_home[j]`` (the first on ties)."""
    best = -1.0
    hire = -1
    for j in range(w.shape[0]):
        if w[j] * to_home[j] > best:
            best = w[j] * to_home[j]
            hire = j
    return hire


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
            C[i, j] = w[j] * dist_to(O, b, fj, O.facilities[b, fi, FAC_X], O.facilities[b, fi, FAC_Y])
    hx = np.empty(N)
    hy = np.empty(N)
    h = retained_homes(b, O, hx, hy)
    # hire map
    p_med = min(h + 1, ns)
    zero = np.zeros(ns)
    is_open = greedy_open(C, zero, p_med)
    local_search(C, zero, is_open, p_med, 1000, 1e-9)
    med = _medians(is_open, ns, p_med)
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
                    D[r, c] = dist_to(O, b, f, hx[r], hy[r])
            col4row = np.empty(h, dtype=np.int64)
            lap_min(D, col4row)
            hire = _first_unmatched(col4row, med)
    else:
        # every site already has someone: the site whose demand is farthest from any home
        to_home = np.full(ns, np.inf)
        for j in range(ns):
            f = sites[j]
            for r in range(h):
                to_home[j] = min(to_home[j], dist_to(O, b, f, hx[r], hy[r]))
        hire = _farthest_site(w, to_home)
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
                d = dist_to(O, b, f, hx[r], hy[r])
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
                d = dist_to(O, b, f, hx[r], hy[r])
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
    h = retained_homes(b, O, hx, hy)
    # hire map
    p_med = min(h + 1, ns)
    is_open, _ = p_median_sparse(ns, cand[:, :kc].copy(), ccost, count, far, p_med, 1000, 1e-9)
    med = _medians(is_open, ns, p_med)
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
        to_home = np.full(ns, np.inf)
        if h > 0:
            to_home[:] = hd[:, 0]
        hire = _farthest_site(w, to_home)
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
