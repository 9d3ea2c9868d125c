"""A compiled rectangular linear assignment solver, callable from numba code.

:func:`scipy.optimize.linear_sum_assignment` is the reference (``wfbench.solvers.assignment``
uses it), but it cannot be called from inside a compiled simulation loop. The
dispatch policy solves one small assignment per step per environment (a few open
requests x tens of free people), so a Python call per environment would cost more
than the solve. :func:`lap_min` is the same method as scipy's, shortest augmenting
paths with dual variables (Crouse, "On implementing 2D rectangular assignment
algorithms", IEEE TAES 2016), written for numba; a test checks that it finds the same
optimal cost as scipy on random instances with ties and forbidden (infinite) pairs.
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            nxt = col4row[i]
            col4row[i] = j
            j = nxt
            if i == cur:
                break
    total = 0.0
    for i in range(nr):
        total += cost[i, col4row[i]]
    return total
