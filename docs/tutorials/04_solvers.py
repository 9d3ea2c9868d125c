# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # The solvers on their own
#
# `solvers` is pure optimization: arrays in, one `SolveResult` out, nothing of the
# simulator ([Solvers](../../solvers/)). The solver-backed policies call it every
# step; here it runs alone on two instances from J.E. Beasley's
# [OR-Library](http://people.brunel.ac.uk/~mastjjb/jeb/orlib/), whose optima are
# published: the linear assignment instance `assign100` and the p-median instance
# `pmed1`. Each is solved by every method, checked against its optimum, and drawn.
# It runs in well under a minute.
#
# Source: [04_solvers.py](04_solvers.py), a jupytext file
# ([how to open it](../01_evaluate_and_compare/)).

# %%
import itertools
import os
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from wfbench.solvers import assignment, facility_location, orlib


def orlib_folder() -> Path:
    """The OR-Library instances: the folder in $ORLIB, or the repository's tests/data/orlib.

    The repository's is found from the working folder or a parent, or (run as a script) from the script's folder.
    """
    if os.environ.get("ORLIB"):
        return Path(os.environ["ORLIB"])
    starts = [Path.cwd()]
    if "__file__" in globals():  # run as a script, from anywhere: also the checkout the script lives in
        starts.append(Path(__file__).resolve().parent)
    for start in starts:
        for folder in (start, *start.parents):
            if (folder / "tests" / "data" / "orlib").is_dir():
                return folder / "tests" / "data" / "orlib"
    raise FileNotFoundError("run this notebook inside a wfbench checkout, or download assign100.txt and "
                            "pmed1.txt from http://people.brunel.ac.uk/~mastjjb/jeb/orlib/files/ into "
                            "assign/ and pmed/ of a folder and set ORLIB to that folder")


ORLIB = orlib_folder()
print(ORLIB)

# %% [markdown]
# ## Assignment, first in miniature
#
# `assignment.solve(cost)` pairs rows with columns at the least total cost; `solution[i]`
# is row i's column. Six people and six open requests on a grid, at Manhattan distance:
# the exact method (scipy's `linear_sum_assignment`) against all 720 pairings.

# %%
rng = np.random.default_rng(7)
people, requests = rng.integers(0, 16, size=(6, 2)), rng.integers(0, 16, size=(6, 2))
cost = np.abs(people[:, None, :] - requests[None, :, :]).sum(axis=2)
toy = assignment.solve(cost)
brute = min(sum(cost[i, j] for i, j in enumerate(perm)) for perm in itertools.permutations(range(6)))
print(f"{toy.status}: total distance {toy.objective:.0f}, all 720 pairings give at best {brute}")
assert toy.objective == brute

fig, ax = plt.subplots(figsize=(4.5, 4.5))
for i, j in enumerate(toy.solution):
    ax.plot(*zip(people[i], requests[j], strict=True), color="gray", lw=1)
ax.scatter(*people.T, marker="o", s=60, label="people", zorder=3)
ax.scatter(*requests.T, marker="s", s=60, label="open requests", zorder=3)
ax.set_xlim(-1, 16), ax.set_ylim(-1, 16), ax.set_aspect("equal")
ax.set_title(f"Optimal dispatch: total distance {toy.objective:.0f}")
ax.legend(loc="upper left", fontsize=8)
plt.show()

# %% [markdown]
# ## `assign100`: 100 x 100, optimum 305
#
# Three methods: `exact` (shortest augmenting paths), `milp` (HiGHS on the 0/1 program)
# and `lp` (the LP relaxation through cvxpy and HiGHS: the assignment polytope is
# integral, so the LP optimum is the integer optimum). Every one must reach the
# published optimum.

# %%
C = orlib.read_assignment(ORLIB / "assign" / "assign100.txt")
ASSIGN100_OPTIMUM = 305
print(C.shape, "costs from", C.min(), "to", C.max())
results = {}
for method in ("exact", "milp", "lp"):
    start = time.perf_counter()
    results[method] = r = assignment.solve(C, method=method)
    print(f"{method:6s} {r.status:8s} objective {r.objective:6.0f}  bound {r.bound:8.2f}  "
          f"{time.perf_counter() - start:6.3f} s  ({r.solver})")
    assert r.objective == ASSIGN100_OPTIMUM
    assert sorted(r.solution) == list(range(100))  # a permutation: every column used once

# %% [markdown]
# The optimum uses almost only the cheapest entries: each row's chosen cost (dots) in
# the cost matrix, and the chosen costs against all of them.

# %%
best = results["exact"].solution
fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
image = left.imshow(C, cmap="Greys")
left.scatter(best, np.arange(100), s=12, color="red", label="chosen pair")
left.set_xlabel("column"), left.set_ylabel("row")
left.set_title("assign100: costs and the optimal assignment")
left.legend(loc="lower left", fontsize=8)
fig.colorbar(image, ax=left, shrink=0.8)
bins = np.arange(C.min(), C.max() + 2) - 0.5
right.hist(C.ravel(), bins=bins, density=True, alpha=0.5, label="all 10,000 costs")
right.hist(C[np.arange(100), best], bins=bins, density=True, alpha=0.7, label="the 100 chosen")
right.set_xlim(C.min() - 1, np.percentile(C, 30))
right.set_xlabel("cost")
right.set_title(f"total {C[np.arange(100), best].sum():.0f} = the published optimum")
right.legend()
fig.tight_layout()
plt.show()

# %% [markdown]
# ## `pmed1`: p-median on a graph, optimum 5819
#
# 100 vertices, 200 weighted edges, p = 5: open 5 medians so that the sum over the
# vertices of the shortest-path distance to the nearest median is least.
# `orlib.read_p_median` returns the all-pairs shortest-path matrix and p (an edge
# listed twice keeps its last cost, as in the published optimum). Three methods: the
# MILP (HiGHS), the LP relaxation with rounding (its value is a lower bound), and the
# compiled greedy + local search (no bound).

# %%
pmed = orlib.read_p_median(ORLIB / "pmed" / "pmed1.txt")
PMED1_OPTIMUM = 5819
print(pmed.dist.shape, "p =", pmed.p)
solved = {}
for method in ("milp", "lp", "local-search"):
    start = time.perf_counter()
    solved[method] = r = facility_location.solve_p_median(pmed.dist, pmed.p, method=method)
    bound = "-" if r.bound is None else f"{r.bound:.1f}"
    print(f"{method:12s} {r.status:8s} objective {r.objective:7.0f}  bound {bound:>7s}  medians {r.solution.tolist()}  "
          f"{time.perf_counter() - start:6.3f} s")
milp = solved["milp"]
assert milp.status == "optimal" and milp.objective == PMED1_OPTIMUM
assert solved["lp"].bound <= PMED1_OPTIMUM <= solved["local-search"].objective

# %% [markdown]
# The graph has no coordinates, so the drawing places the vertices by classical
# multidimensional scaling of the shortest-path distances (an approximate map); the
# edges come from the file. Each vertex is joined to its median.

# %%
tokens = (ORLIB / "pmed" / "pmed1.txt").read_text().split()
n_vertices, n_edges = int(tokens[0]), int(tokens[1])
edges = np.array(tokens[3 : 3 + 3 * n_edges], dtype=float).reshape(n_edges, 3)[:, :2].astype(int) - 1

D2 = pmed.dist**2
J = np.eye(n_vertices) - 1.0 / n_vertices
values, vectors = np.linalg.eigh(-0.5 * J @ D2 @ J)
xy = vectors[:, -2:] * np.sqrt(values[-2:])  # the two leading dimensions

medians = milp.solution
nearest = medians[np.argmin(pmed.dist[medians], axis=0)]  # each vertex's median
assert np.isclose(pmed.dist[nearest, np.arange(n_vertices)].sum(), PMED1_OPTIMUM)

fig, ax = plt.subplots(figsize=(7, 6))
for a, b in edges:
    ax.plot(*xy[[a, b]].T, color="0.85", lw=0.6, zorder=1)
colors = plt.cm.tab10(np.searchsorted(medians, nearest))
for v in range(n_vertices):
    ax.plot(*xy[[v, nearest[v]]].T, color=colors[v], lw=0.8, alpha=0.6, zorder=2)
ax.scatter(*xy.T, c=colors, s=14, zorder=3)
ax.scatter(*xy[medians].T, marker="*", s=350, c=colors[medians], edgecolors="black", zorder=4)
ax.scatter([], [], marker="*", s=200, c="white", edgecolors="black", label="median")  # for the legend
ax.set_title(f"pmed1: the {pmed.p} optimal medians, total distance {milp.objective:.0f}")
ax.set_xticks([]), ax.set_yticks([])
ax.legend(loc="best")
plt.show()

# %% [markdown]
# The same instances and the other 57 of the OR-Library sets (every optimum reached by
# the MILP) are in [Solvers](../../solvers/#or-library-results), run by
# `python benchmarks/orlib.py`. The solver-backed policies that use these methods inside
# the simulator are `solver`, `solver-dispatch`, `solver-workforce` and
# `solver-positioning` (`wfbench policies`).
