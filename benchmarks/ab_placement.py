"""In-process A/B of the hire placement's argmax: the pruned block search against the full scan.

    python benchmarks/ab_placement.py

The baseline is the row-by-row scan of the whole heat map that ``place_hire`` used before
the block search (it is built here from the same helpers, ``heat_factors`` and
``heat_row``). Both run on a ``paper-64`` state after 200 no-op steps, for 200 random
positioning weight vectors, alternated five times in one process (this machine's speed
drifts between runs; see docs/performance.md). Prints microseconds per placement and
checks that both pick the same cells.
"""

import time

import numpy as np
from numba import njit

from wfbench.core.placement import gauss_table, heat_factors, heat_row, place_hire, positioning_weights
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario


@njit
def full_scan(b, S, P, w):
    g = gauss_table(P.sigma, max(P.grid_w, P.grid_h))
    gx, fy = heat_factors(b, S, w, g, P.grid_w)
    row = np.empty(P.grid_w)
    best, bx, by = -1.0, 0, 0
    for y in range(P.grid_h):
        heat_row(row, y, gx, fy, g)
        for x in range(P.grid_w):
            if row[x] > best:
                best, bx, by = row[x], x, y
    return bx, by


@njit
def run_full(S, P, W, out):
    for i in range(W.shape[0]):
        out[i] = full_scan(0, S, P, positioning_weights(0, S, W[i]))


@njit
def run_pruned(S, Tr, P, W, out):
    for i in range(W.shape[0]):
        out[i] = place_hire(0, S, Tr, P, positioning_weights(0, S, W[i]))


sim = Simulator(resolve_scenario("paper-64"), [0])
sim.reset()
noop = {"dispatch": np.full((1, sim.M), sim.N), "workforce": np.zeros(1, np.int64),
        "positioning": np.zeros((1, 2, sim.M))}
for _ in range(200):
    sim.step(noop)
S, Tr, P = sim.state, sim.trace, sim.params
assert P.placement == 0
W = np.random.default_rng(0).random((200, sim.M))
a, b = np.zeros((200, 2), np.int64), np.zeros((200, 2), np.int64)
run_full(S, P, W, a)
run_pruned(S, Tr, P, W, b)
assert np.array_equal(a, b), "the pruned argmax differs from the full scan"
times = {"full scan": [], "pruned": []}
for _ in range(5):
    for name, call in (("full scan", lambda: run_full(S, P, W, a)), ("pruned", lambda: run_pruned(S, Tr, P, W, b))):
        t0 = time.perf_counter()
        for _ in range(10):
            call()
        times[name].append((time.perf_counter() - t0) / 2000 * 1e6)
print(f"{int(S.fac_active[0].sum())} active facilities; us per placement (best, median of 5):")
for name, v in times.items():
    print(f"  {name:10s} {min(v):6.1f} {np.median(v):6.1f}")
