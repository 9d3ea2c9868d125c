"""A compiled rectangular linear assignment solver, callable from numba code.

:func:`lap_min` is scipy's method (shortest augmenting paths with dual variables; Crouse, IEEE
TAES 2016) written for numba, so the compiled dispatch can solve its small per-step assignment
without a Python call; a test checks it finds scipy's optimal cost. For the largest worlds,
:func:`knn_manhattan` (k nearest points through a uniform grid, ties to the lower index) and
:func:`lap_sparse` (the same method on a CSR candidate graph, Dijkstra on a binary heap, an
optional "nobody" column per row; exact on the graph) solve without a dense matrix
(``docs/solvers.md``, "Sparse candidate graphs").
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _augment(path, row4col, col4row, sink, cur):
    """Flip the shortest augmenting path from row ``cur`` to the free column ``sink`` (``path[j]``: row before j)."""
    j = sink
    while True:
        i = path[j]
        row4col[j] = i
        nxt = col4row[i]
        col4row[i] = j
        j = nxt
        if i == cur:
            break


@njit(cache=True)
def lap_min(cost, col4row):
    """Min-cost assignment of every row of ``cost`` (n_rows <= n_cols) to a distinct column.

    Infinite entries are forbidden pairs. Fills ``col4row`` (length n_rows) and returns
    the total cost, or ``inf`` (``col4row`` undefined) when the rows cannot all be
    assigned.
    """
    nr, nc = cost.shape
    u = np.zeros(nr)
    v = np.zeros(nc)
    row4col = np.full(nc, -1, dtype=np.int64)
    col4row[:nr] = -1
    spc = np.empty(nc)  # shortest path cost to each column
    path = np.empty(nc, dtype=np.int64)
    remaining = np.empty(nc, dtype=np.int64)
    in_sr = np.zeros(nr, dtype=np.bool_)
    in_sc = np.zeros(nc, dtype=np.bool_)
    for cur in range(nr):
        spc[:] = np.inf
        path[:] = -1
        in_sr[:] = False
        in_sc[:] = False
        for it in range(nc):
            remaining[it] = nc - 1 - it
        n_rem = nc
        min_val = 0.0
        i = cur
        sink = -1
        while sink == -1:
            in_sr[i] = True
            lowest = np.inf
            index = -1
            for it in range(n_rem):
                j = remaining[it]
                r = min_val + cost[i, j] - u[i] - v[j]
                if r < spc[j]:
                    path[j] = i
                    spc[j] = r
                # prefer a free column on ties: the path ends sooner
                if spc[j] < lowest or (spc[j] == lowest and row4col[j] == -1):
                    lowest = spc[j]
                    index = it
            min_val = lowest
            if not min_val < np.inf:
                return np.inf
            j = remaining[index]
            if row4col[j] == -1:
                sink = j
            else:
                i = row4col[j]
            in_sc[j] = True
            n_rem -= 1
            remaining[index] = remaining[n_rem]
        u[cur] += min_val
        for i in range(nr):
            if in_sr[i] and i != cur:
                u[i] += min_val - spc[col4row[i]]
        for j in range(nc):
            if in_sc[j]:
                v[j] -= min_val - spc[j]
        _augment(path, row4col, col4row, sink, cur)
    total = 0.0
    for i in range(nr):
        total += cost[i, col4row[i]]
    return total


# -- k nearest in Manhattan distance --------------------------------------------------------------
@njit(cache=True, inline="always")
def _better(d, i, bd, bi):
    return d < bd or (d == bd and i < bi)


@njit(cache=True)
def knn_manhattan(qx, qy, px, py, k, idx, dist):
    """The ``k`` nearest points (px, py) of each query (qx, qy), nearest first, ties to the lower point index.

    Fills ``idx`` (n_queries, k) with point indices (-1 past the count) and ``dist`` with
    ``|qx - px| + |qy - py|`` (inf past the count); returns the count per query,
    ``min(k, n_points)``. A uniform grid of about two points per cell is searched ring by
    ring until the k-th distance is below the nearest distance a further ring can hold.
    """
    nq = qx.shape[0]
    n = px.shape[0]
    counts = np.zeros(nq, dtype=np.int64)
    idx[:, :] = -1
    dist[:, :] = np.inf
    if n == 0 or k <= 0 or nq == 0:
        return counts
    x0 = px.min()
    x1 = px.max()
    y0 = py.min()
    y1 = py.max()
    g = max(1, int(np.sqrt(n / 2.0)))
    cw = max((x1 - x0) / g, 1e-9)
    ch = max((y1 - y0) / g, 1e-9)
    cell = np.empty(n, dtype=np.int64)
    start = np.zeros(g * g + 1, dtype=np.int64)
    for p in range(n):
        cx = min(g - 1, int((px[p] - x0) / cw))
        cy = min(g - 1, int((py[p] - y0) / ch))
        cell[p] = cy * g + cx
        start[cell[p] + 1] += 1
    for c in range(g * g):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for p in range(n):  # points in index order within each cell
        order[fill[cell[p]]] = p
        fill[cell[p]] += 1
    step = min(cw, ch)
    kk = min(k, n)
    for q in range(nq):
        x = qx[q]
        y = qy[q]
        qcx = min(g - 1, max(0, int((x - x0) / cw)))
        qcy = min(g - 1, max(0, int((y - y0) / ch)))
        found = 0
        r = 0
        while True:
            for cy in range(max(0, qcy - r), min(g - 1, qcy + r) + 1):
                edge = cy == qcy - r or cy == qcy + r
                for side in range(2 * r + 1 if edge else 2):
                    if edge:
                        cx = qcx - r + side
                    else:
                        cx = qcx - r if side == 0 else qcx + r
                    if cx < 0 or cx > g - 1:
                        continue
                    c = cy * g + cx
                    for t in range(start[c], start[c + 1]):
                        p = order[t]
                        d = abs(x - px[p]) + abs(y - py[p])
                        if found < kk or _better(d, p, dist[q, kk - 1], idx[q, kk - 1]):
                            s = found if found < kk else kk - 1
                            while s > 0 and _better(d, p, dist[q, s - 1], idx[q, s - 1]):
                                dist[q, s] = dist[q, s - 1]
                                idx[q, s] = idx[q, s - 1]
                                s -= 1
                            dist[q, s] = d
                            idx[q, s] = p
                            if found < kk:
                                found += 1
            # a point in ring r + 1 or beyond is at least r * step away (strict: ties keep index order)
            if (found == kk and dist[q, kk - 1] < r * step * (1.0 - 1e-9)) or r > g:
                break
            r += 1
        counts[q] = found
    return counts


# -- assignment on a sparse graph ----------------------------------------------------------------
@njit(cache=True, inline="always")
def heap_push(hk, hj, size, key, j):
    """Add ``(key, j)`` to the min-heap ``hk[:size]``, ``hj[:size]`` (by key, then index); returns the new size.

    The sparse assignment's Dijkstra and the sparse p-median's lazy greedy (on negated gains) share it.
    """
    s = size
    hk[s] = key
    hj[s] = j
    while s > 0:
        par = (s - 1) // 2
        if hk[par] < hk[s] or (hk[par] == hk[s] and hj[par] <= hj[s]):
            break
        hk[par], hk[s] = hk[s], hk[par]
        hj[par], hj[s] = hj[s], hj[par]
        s = par
    return size + 1


@njit(cache=True, inline="always")
def heap_pop(hk, hj, size):
    """Remove the root (smallest key, then index); returns the new size."""
    size -= 1
    hk[0] = hk[size]
    hj[0] = hj[size]
    s = 0
    while True:
        a = 2 * s + 1
        if a >= size:
            break
        b = a + 1
        if b < size and (hk[b] < hk[a] or (hk[b] == hk[a] and hj[b] < hj[a])):
            a = b
        if hk[s] < hk[a] or (hk[s] == hk[a] and hj[s] <= hj[a]):
            break
        hk[a], hk[s] = hk[s], hk[a]
        hj[a], hj[s] = hj[s], hj[a]
        s = a
    return size


@njit(cache=True)
def lap_sparse(nc, indptr, indices, cost, nobody, col4row):
    """Min-cost assignment of every row of a CSR graph to a distinct column, or to its own "nobody".

    Row i's edges are ``indices[indptr[i]:indptr[i + 1]]`` (columns 0..nc-1) at ``cost``;
    ``nobody[i]`` (inf: none) is the cost of leaving it unassigned. Fills ``col4row``
    (-1: nobody) and returns the total cost, or inf (``col4row`` undefined) when the rows
    cannot all be placed. Exact on the graph: shortest augmenting paths with dual
    variables, each path a Dijkstra search over the edges it reaches.
    """
    nr = indptr.shape[0] - 1
    ncol = nc + nr  # column nc + i is row i's nobody
    u = np.zeros(nr)
    v = np.zeros(ncol)
    row4col = np.full(ncol, -1, dtype=np.int64)
    c4r = np.full(nr, -1, dtype=np.int64)
    dist = np.full(ncol, np.inf)
    pred = np.full(ncol, -1, dtype=np.int64)
    done = np.zeros(ncol, dtype=np.bool_)
    touched = np.empty(ncol, dtype=np.int64)
    final = np.empty(ncol, dtype=np.int64)
    cap = indices.shape[0] + nr + 1
    hk = np.empty(cap)
    hj = np.empty(cap, dtype=np.int64)
    # start: a row whose cheapest column is still free takes it (reduced costs stay >= 0 with v = 0)
    for i in range(nr):
        best = nobody[i]
        bj = nc + i
        for e in range(indptr[i], indptr[i + 1]):
            if cost[e] < best or (cost[e] == best and indices[e] < bj):
                best = cost[e]
                bj = indices[e]
        if best < np.inf and row4col[bj] == -1:
            row4col[bj] = i
            c4r[i] = bj
            u[i] = best
    for cur in range(nr):
        if c4r[cur] != -1:
            continue
        nt = 0
        nf = 0
        size = 0
        i = cur
        mv = 0.0
        sink = -1
        while True:
            for e in range(indptr[i], indptr[i + 1] + 1):
                if e < indptr[i + 1]:
                    j = indices[e]
                    c = cost[e]
                else:
                    j = nc + i
                    c = nobody[i]
                    if not c < np.inf:
                        continue
                if done[j]:
                    continue
                r = mv + c - u[i] - v[j]
                if r < dist[j]:
                    if dist[j] == np.inf:
                        touched[nt] = j
                        nt += 1
                    dist[j] = r
                    pred[j] = i
                    size = heap_push(hk, hj, size, r, j)
            j = -1
            while size > 0:
                r = hk[0]
                jj = hj[0]
                size = heap_pop(hk, hj, size)
                if not done[jj] and r == dist[jj]:
                    j = jj
                    break
            if j == -1:
                return np.inf
            done[j] = True
            final[nf] = j
            nf += 1
            mv = dist[j]
            if row4col[j] == -1:
                sink = j
                break
            i = row4col[j]
        u[cur] += mv
        for t in range(nf - 1):
            j = final[t]
            u[row4col[j]] += mv - dist[j]
            v[j] -= mv - dist[j]
        _augment(pred, row4col, c4r, sink, cur)
        for t in range(nt):
            j = touched[t]
            dist[j] = np.inf
            pred[j] = -1
            done[j] = False
    total = 0.0
    for i in range(nr):
        j = c4r[i]
        if j >= nc:
            total += nobody[i]
            col4row[i] = -1
        else:
            col4row[i] = j
            for e in range(indptr[i], indptr[i + 1]):
                if indices[e] == j:
                    total += cost[e]
                    break
    return total
