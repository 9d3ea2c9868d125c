"""Positioning through a heat map: where a hire lives, whose home is hottest.

The heat map is ``H(x, y) = sum_f w_f exp(-|(x, y) - (x_f, y_f)|^2 / (2 sigma^2))`` over the
active facilities (all-zero weights: every one weighs 1). A hire lives at the first hottest cell
in row-major order (``placement = "argmax"``) or a cell drawn in proportion to the heat
(``"sample"``); a let-go takes the person of the level whose home is hottest. The functions work
on environment ``b`` and allocate only scratch; every cell sums its facilities in slot order, so
all traversals give the same values bit for bit. The rule: ``docs/model.md``; ``docs/design.md``,
"Positioning through a heat map".
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wfbench.core.rng import STREAM_PLACEMENT, uniform


@njit(cache=True)
def positioning_weights(b, S, w):
    """Positioning weights on active facilities; all-zero weights mean 'no preference'."""
    M = S.fac_active.shape[1]
    out = np.zeros(M)
    total = 0.0
    for f in range(M):
        if S.fac_active[b, f]:
            out[f] = w[f]
            total += w[f]
    if total <= 0.0:
        for f in range(M):
            if S.fac_active[b, f]:
                out[f] = 1.0
    return out


@njit(cache=True)
def gauss_table(sigma, n):
    """``g[d] = exp(-d^2 / (2 sigma^2))`` for the integer distances d = 0..n-1.

    Homes and facilities sit on integer cells, so every Gaussian factor of the heat map
    is one of these; the table turns two exponentials per (cell, facility) into lookups.
    Each entry is the same expression the direct computation evaluates, so the heat map
    is bit-identical to it.
    """
    inv = 1.0 / (2.0 * sigma * sigma)
    g = np.empty(n)
    for d in range(n):
        g[d] = np.exp(-(d * d) * inv)
    return g


@njit(cache=True, inline="always")
def heat_at(b, S, w, g, x, y):
    """H(x, y) = sum_f w_f exp(-|(x, y) - x_f|^2 / (2 sigma^2)) over the weights ``w``.

    ``g`` is the table of :func:`gauss_table`.
    """
    h = 0.0
    for f in range(S.fac_active.shape[1]):
        if w[f] > 0.0:
            h += w[f] * g[abs(x - S.fac_x[b, f])] * g[abs(y - S.fac_y[b, f])]
    return h


@njit(cache=True)
def heat_terms(b, S, w):
    """Weights and cells (k,) of the k facilities with w_f > 0, in slot order."""
    M = S.fac_active.shape[1]
    k = 0
    for f in range(M):
        if w[f] > 0.0:
            k += 1
    wk = np.empty(k)
    xk = np.empty(k, dtype=np.int64)
    yk = np.empty(k, dtype=np.int64)
    k = 0
    for f in range(M):
        if w[f] > 0.0:
            wk[k] = w[f]
            xk[k] = S.fac_x[b, f]
            yk[k] = S.fac_y[b, f]
            k += 1
    return wk, xk, yk


@njit(cache=True)
def heat_factors(b, S, w, g, grid_w):
    """The x factors ``w_f g[|x - x_f|]`` (k, grid_w) and the y cells (k,) of the k facilities with w_f > 0."""
    wk, xk, yk = heat_terms(b, S, w)
    gx = np.empty((wk.shape[0], grid_w))
    for k in range(wk.shape[0]):
        for x in range(grid_w):
            gx[k, x] = wk[k] * g[abs(x - xk[k])]
    return gx, yk


@njit(cache=True, inline="always")
def heat_row(row, y, gx, fy, g):
    """Row y of the heat map, H(x, y) = sum_f (w_f g[|x - x_f|]) g[|y - y_f|], summed in slot order."""
    row[:] = 0.0
    for k in range(gx.shape[0]):
        gy = g[abs(y - fy[k])]
        for x in range(row.shape[0]):
            row[x] += gx[k, x] * gy


HEAT_BLOCK = 4  # cells per side of the blocks the argmax placement bounds


@njit(cache=True, inline="always")
def _gap(c, lo, hi):
    """Distance from cell ``c`` to the nearest cell of ``lo..hi`` (0 inside)."""
    if c < lo:
        return lo - c
    if c > hi:
        return c - hi
    return 0


@njit(cache=True)
def _block_argmax(wk, xk, yk, g, grid_w, x0, x1, y0, y1, best, best_i, ax, row):
    """Fold the cells x0..x1-1, y0..y1-1 into the running argmax (value, row-major index, first on ties).

    ``ax`` (K, >= x1 - x0) and ``row`` (>= x1 - x0) are scratch. A cell's value is
    ``sum_k (wk g[|x - xk|]) g[|y - yk|]`` in facility order, as on the full map.
    """
    n = x1 - x0
    for k in range(wk.shape[0]):
        for j in range(n):
            ax[k, j] = wk[k] * g[abs(x0 + j - xk[k])]
    for y in range(y0, y1):
        row[:n] = 0.0
        for k in range(wk.shape[0]):
            gy = g[abs(y - yk[k])]
            for j in range(n):
                row[j] += ax[k, j] * gy
        for j in range(n):
            h = row[j]
            i = y * grid_w + x0 + j
            if h > best or (h == best and i < best_i):
                best = h
                best_i = i
    return best, best_i


@njit(cache=True)
def full_argmax(wk, xk, yk, g, grid_w, grid_h):
    """The first cell (row-major) of maximal heat, every cell evaluated."""
    ax = np.empty((wk.shape[0], grid_w))
    row = np.empty(grid_w)
    return _block_argmax(wk, xk, yk, g, grid_w, 0, grid_w, 0, grid_h, -1.0, 0, ax, row)[1]


@njit(cache=True)
def argmax_heat(wk, xk, yk, g, grid_w, grid_h):
    """The first cell (row-major) of maximal heat ``H(x, y) = sum_k wk g[|x - xk|] g[|y - yk|]``.

    Only blocks of ``HEAT_BLOCK`` x ``HEAT_BLOCK`` cells that can hold the maximum are
    evaluated. A block's bound takes, for each facility, the factors at the block's
    cell nearest to it; where the table ``g`` decreases with the distance, every term of
    a cell's value is at most the same term of its block's bound, and IEEE rounding is
    monotone, so the computed value of every cell is at most the computed bound (no
    margin needed). Blocks are visited from the highest bound, then in row-major order,
    and skipped when their bound is below the best value found. Each cell sums its
    facilities in order, exactly as a full scan does, so the result is the full scan's
    bit for bit (``tests/core/test_heat_placement.py`` checks this).
    """
    K = wk.shape[0]
    for d in range(1, g.shape[0]):
        if g[d] > g[d - 1]:  # not decreasing (never seen): the bounds would not hold
            return full_argmax(wk, xk, yk, g, grid_w, grid_h)
    blk = HEAT_BLOCK
    nbx = (grid_w + blk - 1) // blk
    nby = (grid_h + blk - 1) // blk
    bx = np.empty((K, nbx))
    for k in range(K):
        for X in range(nbx):
            bx[k, X] = wk[k] * g[_gap(xk[k], X * blk, min(grid_w, X * blk + blk) - 1)]
    ub = np.zeros((nby, nbx))
    for Y in range(nby):
        for k in range(K):
            gy = g[_gap(yk[k], Y * blk, min(grid_h, Y * blk + blk) - 1)]
            for X in range(nbx):
                ub[Y, X] += bx[k, X] * gy
    top = 0
    for j in range(nby * nbx):
        if ub[j // nbx, j % nbx] > ub[top // nbx, top % nbx]:
            top = j
    Y, X = top // nbx, top % nbx
    ax = np.empty((K, blk))
    row = np.empty(blk)
    best, best_i = _block_argmax(wk, xk, yk, g, grid_w, X * blk, min(grid_w, X * blk + blk), Y * blk,
                                 min(grid_h, Y * blk + blk), -1.0, 0, ax, row)
    for Y in range(nby):
        for X in range(nbx):
            if Y * nbx + X != top and ub[Y, X] >= best:
                best, best_i = _block_argmax(wk, xk, yk, g, grid_w, X * blk, min(grid_w, X * blk + blk), Y * blk,
                                             min(grid_h, Y * blk + blk), best, best_i, ax, row)
    return best_i


@njit(cache=True)
def place_hire(b, S, Tr, P, w):
    """Home cell of a hire: argmax of H (first cell in row-major order on ties) or a draw from H.

    Each cell sums its facilities in slot order, so the values are the same whichever
    way the map is traversed: the argmax evaluates only the blocks that can hold it
    (:func:`argmax_heat`), the draw builds the map once, row by row.
    """
    g = gauss_table(P.sigma, max(P.grid_w, P.grid_h))
    if P.placement == 0:
        wk, xk, yk = heat_terms(b, S, w)
        i = argmax_heat(wk, xk, yk, g, P.grid_w, P.grid_h)
        return i % P.grid_w, i // P.grid_w
    gx, fy = heat_factors(b, S, w, g, P.grid_w)
    heat = np.empty((P.grid_h, P.grid_w))
    total = 0.0
    for y in range(P.grid_h):
        heat_row(heat[y], y, gx, fy, g)
        for x in range(P.grid_w):
            total += heat[y, x]
    u = uniform(Tr.key[b], STREAM_PLACEMENT, S.n_hires[b], 0, 0) * total
    acc = 0.0
    for y in range(P.grid_h):
        for x in range(P.grid_w):
            acc += heat[y, x]
            if acc > u:
                return x, y
    return P.grid_w - 1, P.grid_h - 1
