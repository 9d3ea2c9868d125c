"""The pruned argmax of the hire heat map is the full scan's argmax, bit for bit.

``argmax_heat`` evaluates only the blocks of cells whose bound can reach the best value
found; these tests compare it with an exhaustive scan (compiled, and in plain Python with
the same arithmetic) on random maps, on ties, on underflowing tables and on a table that
does not decrease (where the bound would not hold and the full scan must be used).
"""

import numpy as np
import pytest

from wfbench.core.placement import argmax_heat, full_argmax, gauss_table


def python_argmax(wk, xk, yk, g, grid_w, grid_h):
    best, best_i = -1.0, 0
    for y in range(grid_h):
        for x in range(grid_w):
            h = 0.0
            for k in range(len(wk)):
                h += float(wk[k]) * float(g[abs(x - xk[k])]) * float(g[abs(y - yk[k])])
            if h > best:
                best, best_i = h, y * grid_w + x
    return best_i


def terms(rng, k, grid_w, grid_h):
    return rng.random(k), rng.integers(0, grid_w, k), rng.integers(0, grid_h, k)


@pytest.mark.parametrize("grid_w,grid_h,sigma", [(64, 64, 6.0), (13, 7, 2.0), (9, 30, 0.5), (5, 5, 40.0)])
def test_pruned_argmax_equals_full_scan(grid_w, grid_h, sigma):
    rng = np.random.default_rng(grid_w * 1000 + grid_h)
    g = gauss_table(sigma, max(grid_w, grid_h))
    for trial in range(60):
        wk, xk, yk = terms(rng, int(rng.integers(1, 30)), grid_w, grid_h)
        if trial % 3 == 0:  # coarse weights make equal values likely
            wk = np.round(wk * 2) / 2
        expected = full_argmax(wk, xk, yk, g, grid_w, grid_h)
        assert argmax_heat(wk, xk, yk, g, grid_w, grid_h) == expected
        if grid_w * grid_h < 400:
            assert expected == python_argmax(wk, xk, yk, g, grid_w, grid_h)


def test_ties_go_to_the_first_cell_in_row_major_order():
    g = gauss_table(3.0, 32)
    # two equal facilities mirrored about the centre: equal maxima at both, the upper-left one wins
    wk, xk, yk = np.array([1.0, 1.0]), np.array([20, 5]), np.array([20, 5])
    assert argmax_heat(wk, xk, yk, g, 32, 32) == 5 * 32 + 5
    # no facility with a positive weight: the map is all zero and the first cell wins
    none = np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    assert argmax_heat(*none, g, 32, 32) == 0


def test_underflowing_table_ties_on_zero_values():
    # sigma 0.2: the factors underflow to 0 a few cells away, so most of the map is exactly 0
    g = gauss_table(0.2, 40)
    assert g[-1] == 0.0
    rng = np.random.default_rng(7)
    for _ in range(30):
        wk, xk, yk = terms(rng, 3, 40, 40)
        assert argmax_heat(wk, xk, yk, g, 40, 40) == full_argmax(wk, xk, yk, g, 40, 40)


def test_non_decreasing_table_falls_back_to_the_full_scan():
    # a table that grows with the distance breaks the block bound; the result must still be exact
    g = np.linspace(0.1, 1.0, 16)
    rng = np.random.default_rng(3)
    for _ in range(20):
        wk, xk, yk = terms(rng, 4, 16, 16)
        expected = python_argmax(wk, xk, yk, g, 16, 16)
        assert argmax_heat(wk, xk, yk, g, 16, 16) == expected

