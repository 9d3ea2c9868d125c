"""The positioning oracle's maps: hire at the p-median of the known future demand, let go the cheapest loss.

The known future demand is the cells where requests open in an exact roll-forward
(:func:`wfbench.policies.kernels.forward.roll_forward` with ``record=True``), each a client
weighted by its requests. :func:`hire_sites` gives the p-median's unmatched median
(:func:`wfbench.solvers.facility_location.solve_p_median`, matched to the homes by
:func:`wfbench.solvers.assignment.solve`) and the best single addition; :func:`release_targets`
the person per level whose removal costs least. A map is a (2, M) positioning action: row 0
read by a hire, row 1 by a let-go (``docs/hindsight.md``, "Positioning oracle").
"""

from __future__ import annotations

import numpy as np
from wfbench.solvers.assignment import solve as solve_assignment
from wfbench.solvers.facility_location import solve_p_median


def demand_clients(onset_xy: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Distinct cells (k, 2) of the first ``n`` recorded request onsets and their counts (k,)."""
    n = min(int(n), onset_xy.shape[0])
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    cells, counts = np.unique(onset_xy[:n], axis=0, return_counts=True)
    return cells, counts.astype(np.float64)


def _manhattan(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) Manhattan distances between cells."""
    return np.abs(a[:, None, 0] - b[None, :, 0]) + np.abs(a[:, None, 1] - b[None, :, 1])


def hire_sites(sites: np.ndarray, homes: np.ndarray, cells: np.ndarray, counts: np.ndarray) -> tuple[int, int]:
    """Indices into ``sites`` of the p-median hire site and of the best single addition.

    Args:
        sites: (ns, 2) candidate cells (the active facilities).
        homes: (h, 2) homes of the retained workforce.
        cells: (k, 2) demand cells.
        counts: (k,) their weights (requests per cell).

    Returns:
        (p-median site, best-addition site); -1 for both when there is no site.
    """
    ns = sites.shape[0]
    if ns == 0 or cells.shape[0] == 0:
        return -1, -1
    D = _manhattan(sites, cells).astype(np.float64)  # (ns, k)
    h = homes.shape[0]
    # the best single addition to the current homes
    if h > 0:
        near = _manhattan(homes, cells).min(axis=0).astype(np.float64)
        gain = (counts[None, :] * np.maximum(0.0, near[None, :] - D)).sum(axis=1)
    else:
        gain = -(counts[None, :] * D).sum(axis=1)
    greedy = int(np.argmax(gain))
    p = min(h + 1, ns)
    if p <= h:  # every site could already have someone: the p-median adds nothing new
        return greedy, greedy
    res = solve_p_median(D, p, method="local-search", weights=counts)
    med = np.asarray(res.solution, dtype=np.int64)
    if h == 0:
        return int(med[0]), greedy
    # homes (rows, h < p) to medians (columns): the unmatched median is the site the workforce lacks
    H = _manhattan(homes, sites[med]).astype(np.float64)
    match = solve_assignment(H, method="exact").solution
    taken = np.zeros(p, dtype=bool)
    taken[match[match >= 0]] = True
    free = np.flatnonzero(~taken)
    return (int(med[free[0]]) if free.size else greedy), greedy


def release_targets(homes: np.ndarray, levels: np.ndarray, releasable: np.ndarray, cells: np.ndarray,
                    counts: np.ndarray) -> np.ndarray:
    """For each level, the index into ``homes`` of the releasable person whose removal costs least (-1: none).

    The cost of removing person r is ``sum_c w_c (d2(c) - d1(c))`` over the demand cells
    c whose nearest home is r's (d1, d2: distances to the nearest and second nearest
    home); ties go to the lowest index.
    """
    h = homes.shape[0]
    out = np.full(3, -1, dtype=np.int64)
    if h == 0:
        return out
    delta = np.zeros(h)
    if h >= 2 and cells.shape[0] > 0:
        D = _manhattan(homes, cells).astype(np.float64)  # (h, k)
        order = np.argsort(D, axis=0, kind="stable")
        d1 = np.take_along_axis(D, order[:1], axis=0)[0]
        d2 = np.take_along_axis(D, order[1:2], axis=0)[0]
        np.add.at(delta, order[0], counts * (d2 - d1))
    for lv in range(3):
        idx = np.flatnonzero(releasable & (levels == lv))
        if idx.size:
            out[lv] = int(idx[np.argmin(delta[idx])])
    return out


def one_hot_map(M: int, row: int, slot: int, fallback: np.ndarray) -> np.ndarray:
    """A (2, M) positioning action with weight 1 on facility ``slot`` in ``row`` (``fallback`` when slot < 0)."""
    if slot < 0:
        return fallback.copy()
    out = np.zeros((2, M))
    out[row, slot] = 1.0
    return out


def nearest_slot(slots: np.ndarray, sites: np.ndarray, cell: np.ndarray) -> int:
    """The facility slot (of ``slots``, cells ``sites``) nearest ``cell``, lowest slot on ties (-1: none)."""
    if slots.size == 0:
        return -1
    d = np.abs(sites[:, 0] - cell[0]) + np.abs(sites[:, 1] - cell[1])
    return int(slots[np.argmin(d)])
