"""Uncapacitated facility location (UFL) and p-median.

UFL opens a set S of facilities (fixed cost ``f_i``) and serves every client from its cheapest
open one: minimize ``sum_{i in S} f_i + sum_j min_{i in S} c_ij``; p-median has no fixed costs,
exactly ``|S| = p`` and optional client weights. Rows are candidate facilities, columns clients.
:func:`solve_ufl` and :func:`solve_p_median` take ``"milp"`` (the strong formulation, HiGHS),
``"lp"`` (relaxation and rounding; the LP value is the bound) or ``"local-search"`` (greedy, then
add/drop/swap with Whitaker's fast interchange). :func:`p_median_sparse` is the compiled search on
k-nearest candidate lists. ``docs/solvers.md``, "Facility location" and "Sparse candidate graphs".
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from numba import njit
from wfbench.solvers.lap import heap_pop, heap_push
from wfbench.solvers.result import (
    FEASIBLE,
    OPTIMAL,
    OSQP_POLISH,
    TIME_LIMIT,
    SolveResult,
    SolverInputError,
    Timer,
    as_matrix,
    as_vector,
    check_method,
    check_time_limit,
    relative_gap,
    without_highs_stray,
)

METHODS = ("milp", "lp", "local-search")
LP_SOLVERS = ("HIGHS", "OSQP")


# -- local search (compiled) ---------------------------------------------------------------------
@njit(cache=True)
def _nearest_two(C, is_open, d1, a1, d2):
    m, n = C.shape
    for j in range(n):
        b1 = np.inf
        b2 = np.inf
        ai = -1
        for i in range(m):
            if is_open[i]:
                c = C[i, j]
                if c < b1:
                    b2 = b1
                    b1 = c
                    ai = i
                elif c < b2:
                    b2 = c
        d1[j] = b1
        a1[j] = ai
        d2[j] = b2


@njit(cache=True)
def _cost(C, f, is_open):
    m, n = C.shape
    total = 0.0
    for i in range(m):
        if is_open[i]:
            total += f[i]
    for j in range(n):
        b = np.inf
        for i in range(m):
            if is_open[i] and C[i, j] < b:
                b = C[i, j]
        total += b
    return total


@njit(cache=True)
def greedy_open(C, f, p):
    """Greedy construction: p > 0 adds exactly p facilities, p == 0 adds while the cost drops."""
    m, n = C.shape
    is_open = np.zeros(m, dtype=np.bool_)
    d1 = np.full(n, np.inf)
    n_open = 0
    while True:
        best = np.inf
        bi = -1
        for i in range(m):
            if is_open[i]:
                continue
            delta = f[i]
            for j in range(n):
                if n_open == 0:
                    delta += C[i, j]
                elif C[i, j] < d1[j]:
                    delta += C[i, j] - d1[j]
            if delta < best:
                best = delta
                bi = i
        if bi < 0:
            break
        if p == 0 and n_open > 0 and best >= 0.0:
            break
        is_open[bi] = True
        n_open += 1
        for j in range(n):
            if C[bi, j] < d1[j]:
                d1[j] = C[bi, j]
        if p > 0 and n_open == p:
            break
    return is_open


@njit(cache=True)
def local_search(C, f, is_open, p, max_iter, tol):
    """Best-improvement add / drop / swap (swap only when p > 0) from ``is_open`` (changed in place)."""
    m, n = C.shape
    d1 = np.empty(n)
    d2 = np.empty(n)
    a1 = np.empty(n, dtype=np.int64)
    loss = np.empty(m)
    it = 0
    while it < max_iter:
        it += 1
        _nearest_two(C, is_open, d1, a1, d2)
        n_open = 0
        for i in range(m):
            if is_open[i]:
                n_open += 1
        best = -tol
        move = 0  # 1 add k, 2 drop r, 3 swap r -> k
        bk = -1
        br = -1
        # drop r: its clients go to their second nearest
        if p == 0 and n_open > 1:
            for i in range(m):
                loss[i] = -f[i] if is_open[i] else 0.0
            for j in range(n):
                loss[a1[j]] += d2[j] - d1[j]
            for r in range(m):
                if is_open[r] and loss[r] < best:
                    best = loss[r]
                    move = 2
                    br = r
        for k in range(m):
            if is_open[k]:
                continue
            gain = f[k]
            for i in range(m):
                loss[i] = 0.0
            for j in range(n):
                c = C[k, j]
                if c < d1[j]:
                    gain += c - d1[j]
                else:
                    loss[a1[j]] += min(c, d2[j]) - d1[j]
            if p == 0 and gain < best:
                best = gain
                move = 1
                bk = k
            for r in range(m):
                if is_open[r]:
                    delta = gain - f[r] + loss[r]
                    if delta < best:
                        best = delta
                        move = 3
                        bk = k
                        br = r
        if move == 0:
            break
        if move == 1:
            is_open[bk] = True
        elif move == 2:
            is_open[br] = False
        else:
            is_open[bk] = True
            is_open[br] = False
    return it


# -- p-median on candidate lists -----------------------------------------------------------------
@njit(cache=True, inline="always")
def _gain(rp, rj, rc, d1, i, first):
    """Cost saved by opening site i (``first``: no site open yet, the dense greedy's minus-sum form)."""
    s = 0.0
    if first:
        for e in range(rp[i], rp[i + 1]):
            s += rc[e]
        return -s
    for e in range(rp[i], rp[i + 1]):
        j = rj[e]
        if rc[e] < d1[j]:
            s += d1[j] - rc[e]
    return s


@njit(cache=True)
def reverse_lists(m, cand, ccost, count):
    """Site -> its clients (ascending), with the costs: the CSR transpose of the client lists ``cand``."""
    n = cand.shape[0]
    rp = np.zeros(m + 1, dtype=np.int64)
    for j in range(n):
        for t in range(count[j]):
            rp[cand[j, t] + 1] += 1
    for i in range(m):
        rp[i + 1] += rp[i]
    fill = rp[:-1].copy()
    rj = np.empty(rp[m], dtype=np.int64)
    rc = np.empty(rp[m])
    for j in range(n):
        for t in range(count[j]):
            i = cand[j, t]
            rj[fill[i]] = j
            rc[fill[i]] = ccost[j, t]
            fill[i] += 1
    return rp, rj, rc


@njit(cache=True)
def _nearest_two_sparse(cand, ccost, count, far, is_open, d1, a1, d2):
    """Each client's cheapest and second-cheapest open candidate (``far`` standing for every other site)."""
    for j in range(cand.shape[0]):
        b1 = far[j]
        b2 = far[j]
        ai = -1
        for t in range(count[j]):
            i = cand[j, t]
            if is_open[i]:
                c = ccost[j, t]
                if c < b1 or (c == b1 and (ai < 0 or i < ai)):
                    b2 = b1
                    b1 = c
                    ai = i
                elif c < b2:
                    b2 = c
        d1[j] = b1
        a1[j] = ai
        d2[j] = b2


@njit(cache=True)
def p_median_sparse(m, cand, ccost, count, far, p, max_iter, tol):
    """Open ``p`` of ``m`` sites: lazy greedy, then best-improvement swaps, on the candidate lists.

    ``cand`` (n, k) are client j's candidate sites (its k nearest), ``ccost`` the costs
    (weight x distance), ``count`` how many are valid, ``far[j]`` the cost of serving j
    from any other site (inf when the lists are complete). Returns the open flags and the
    number of swap iterations.
    """
    n = cand.shape[0]
    rp, rj, rc = reverse_lists(m, cand, ccost, count)
    is_open = np.zeros(m, dtype=np.bool_)
    d1 = far.copy()
    complete = True
    for j in range(n):
        if far[j] < np.inf:
            complete = False
    # lap's min-heap on (-gain, site): the largest gain first, the lower site on a tie
    hg = np.empty(max(m, 1))  # a pop precedes every push after the build: at most m entries
    hi = np.empty(hg.shape[0], dtype=np.int64)
    n_open = 0
    size = 0
    while n_open < p:
        first = complete and n_open == 0
        if n_open == 0 or (complete and n_open == 1):  # (re)build: the first gains are not bounds of the later
            size = 0
            for i in range(m):
                if not is_open[i]:
                    size = heap_push(hg, hi, size, -_gain(rp, rj, rc, d1, i, first), i)
        bi = -1
        while size > 0:
            i = hi[0]
            size = heap_pop(hg, hi, size)
            g = -_gain(rp, rj, rc, d1, i, first)
            if size == 0 or not (hg[0] < g or (hg[0] == g and hi[0] < i)):  # still ahead of every bound left
                bi = i
                break
            size = heap_push(hg, hi, size, g, i)
        if bi < 0:
            break
        is_open[bi] = True
        n_open += 1
        for e in range(rp[bi], rp[bi + 1]):
            j = rj[e]
            if rc[e] < d1[j]:
                d1[j] = rc[e]
    # best-improvement swaps (the dense local_search's move, on the lists)
    d2 = np.empty(n)
    a1 = np.empty(n, dtype=np.int64)
    base = np.zeros(m)
    corr = np.zeros(m)
    mark = np.zeros(m, dtype=np.bool_)
    tl = np.empty(m, dtype=np.int64)
    it = 0
    while it < max_iter:
        it += 1
        _nearest_two_sparse(cand, ccost, count, far, is_open, d1, a1, d2)
        base[:] = 0.0
        for j in range(n):
            if a1[j] >= 0:
                base[a1[j]] += d2[j] - d1[j]
        opened = np.flatnonzero(is_open)
        keys = np.empty(opened.shape[0])
        for t in range(opened.shape[0]):
            keys[t] = base[opened[t]]
        srt = opened[np.argsort(keys, kind="mergesort")]  # by (base, site)
        best = -tol
        bk = -1
        br = -1
        for k in range(m):
            if is_open[k]:
                continue
            gain = 0.0
            nt = 0
            for e in range(rp[k], rp[k + 1]):
                j = rj[e]
                c = rc[e]
                r = a1[j]
                if c < d1[j]:
                    gain += c - d1[j]
                    if r >= 0:
                        if not mark[r]:
                            mark[r] = True
                            corr[r] = 0.0
                            tl[nt] = r
                            nt += 1
                        corr[r] -= d2[j] - d1[j]
                elif r >= 0:
                    if not mark[r]:
                        mark[r] = True
                        corr[r] = 0.0
                        tl[nt] = r
                        nt += 1
                    corr[r] += min(c, d2[j]) - d2[j]
            # the best site to close: the smallest base among the untouched, or a touched one
            lr = -1
            lv = np.inf
            for t in range(srt.shape[0]):
                if not mark[srt[t]]:
                    lr = srt[t]
                    lv = base[lr]
                    break
            for t in range(nt):
                r = tl[t]
                val = base[r] + corr[r]
                if val < lv or (val == lv and r < lr):
                    lv = val
                    lr = r
                mark[r] = False
            if lr >= 0:
                delta = gain + lv
                if delta < best:
                    best = delta
                    bk = k
                    br = lr
        if bk < 0:
            break
        is_open[bk] = True
        is_open[br] = False
    return is_open, it


def _assignment(C: np.ndarray, is_open: np.ndarray) -> np.ndarray:
    rows = np.flatnonzero(is_open)
    return rows[np.argmin(C[rows], axis=0)]


def _objective(C: np.ndarray, f: np.ndarray, is_open: np.ndarray) -> float:
    rows = np.flatnonzero(is_open)
    return float(f[rows].sum() + C[rows].min(axis=0).sum())


def _result(status, C, f, is_open, bound, seconds, solver, method, message="", **detail) -> SolveResult:
    obj = _objective(C, f, is_open)
    detail = {"assignment": _assignment(C, is_open), **detail}
    return SolveResult(status, obj, np.flatnonzero(is_open), bound, seconds, solver, method,
                       gap=relative_gap(obj, bound), message=message, detail=detail)


def _heuristic(C, f, p, time_limit=None):
    is_open = greedy_open(C, f, p)
    greedy_obj = _objective(C, f, is_open)
    iters = local_search(C, f, is_open, p, 10_000_000, 1e-9 * max(1.0, abs(greedy_obj)))
    return is_open, greedy_obj, iters


# -- MILP and LP ---------------------------------------------------------------------------------
def _milp(C, f, p, time_limit):
    # imported here: the compiled policies import this module for greedy_open and
    # local_search and would otherwise pay for scipy.optimize at start-up
    import scipy.sparse as sp
    from scipy.optimize import Bounds, LinearConstraint, milp

    m, n = C.shape
    nx = m * n
    # variable order: y_0..y_{m-1}, then x_ij row-major (i, j) at m + i * n + j
    obj = np.concatenate([f, C.ravel()])
    idx = np.arange(nx)
    i_of = idx // n
    j_of = idx % n
    assign = sp.csr_matrix((np.ones(nx), (j_of, m + idx)), shape=(n, m + nx))
    link = sp.csr_matrix(
        (np.concatenate([np.ones(nx), -np.ones(nx)]), (np.concatenate([idx, idx]), np.concatenate([m + idx, i_of]))),
        shape=(nx, m + nx),
    )
    cons = [LinearConstraint(assign, 1.0, 1.0), LinearConstraint(link, -np.inf, 0.0)]
    if p:
        cons.append(LinearConstraint(sp.csr_matrix((np.ones(m), (np.zeros(m), np.arange(m))), shape=(1, m + nx)), p, p))
    integrality = np.concatenate([np.ones(m), np.zeros(nx)])
    options: dict[str, Any] = {"disp": False}
    if time_limit is not None:
        options["time_limit"] = time_limit
    with without_highs_stray():
        return milp(obj, integrality=integrality, bounds=Bounds(0.0, 1.0), constraints=cons, options=options)


def _lp(C, f, p, lp_solver, time_limit):
    import cvxpy as cp

    m, n = C.shape
    y = cp.Variable(m)
    X = cp.Variable((m, n), nonneg=True)
    cons = [cp.sum(X, axis=0) == 1, X <= cp.reshape(y, (m, 1), order="C") @ np.ones((1, n)), y <= 1, y >= 0]
    if p:
        cons.append(cp.sum(y) == p)
    prob = cp.Problem(cp.Minimize(f @ y + cp.sum(cp.multiply(C, X))), cons)
    kwargs: dict[str, Any] = {}
    if lp_solver == "OSQP":
        kwargs = {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iter": 100_000, **OSQP_POLISH}
    if time_limit is not None:
        kwargs["time_limit"] = time_limit
    with warnings.catch_warnings():
        # an inaccurate solve shows in the status, which the result's message reports
        warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
        prob.solve(solver=getattr(cp, lp_solver), **kwargs)
    return prob, y.value, X.value


def _round(y: np.ndarray, X: np.ndarray, p: int) -> np.ndarray:
    m = y.size
    is_open = np.zeros(m, dtype=bool)
    if p:
        is_open[np.argsort(-y, kind="stable")[:p]] = True
        return is_open
    is_open[y >= 0.5 - 1e-9] = True
    served = X[is_open].sum(axis=0) if is_open.any() else np.zeros(X.shape[1])
    for j in np.flatnonzero(served < 0.5):
        is_open[int(np.argmax(X[:, j]))] = True
    return is_open


def _solve(C: np.ndarray, f: np.ndarray, p: int, method: str, lp_solver: str, time_limit: float | None,
           what: str) -> SolveResult:
    solver = {"milp": "HiGHS (scipy.milp)", "lp": f"cvxpy/{lp_solver}", "local-search": "greedy + local search"}[method]
    with Timer() as clock:
        if method == "local-search":
            is_open, greedy_obj, iters = _heuristic(C, f, p)
            return _result(FEASIBLE, C, f, is_open, None, clock.elapsed, solver, method,
                           greedy_objective=greedy_obj, iterations=iters)
        if method == "milp":
            res = _milp(C, f, p, time_limit)
            bound = getattr(res, "mip_dual_bound", None)
            bound = None if bound is None or not math.isfinite(bound) else float(bound)
            if res.x is None:
                if res.status != 1:
                    raise RuntimeError(f"{what}: HiGHS reports {res.message!r} on a problem that is always feasible")
                is_open, _, _ = _heuristic(C, f, p)
                return _result(TIME_LIMIT, C, f, is_open, bound, clock.elapsed, solver, method,
                               message="time limit before HiGHS found an incumbent; solution from local search")
            is_open = res.x[: C.shape[0]] > 0.5
            if res.status == 0:
                return _result(OPTIMAL, C, f, is_open, _objective(C, f, is_open), clock.elapsed, solver, method,
                               message=str(res.message))
            return _result(TIME_LIMIT, C, f, is_open, bound, clock.elapsed, solver, method, message=str(res.message))
        prob, y, X = _lp(C, f, p, lp_solver, time_limit)
        if y is None:
            raise RuntimeError(f"{what}: {lp_solver} returned no LP solution (status {prob.status})")
        is_open = _round(np.asarray(y), np.asarray(X), p)
        lp_value = float(prob.value)
        # only an LP solved to optimality by HiGHS is a certified bound (OSQP is first-order)
        bound = lp_value if lp_solver == "HIGHS" and prob.status == "optimal" else None
        obj = _objective(C, f, is_open)
        proven = bound is not None and obj <= bound + 1e-9 * max(1.0, abs(bound))
        return _result(OPTIMAL if proven else FEASIBLE, C, f, is_open, bound, clock.elapsed, solver, method,
                       message=f"LP status {prob.status}", lp_y=np.asarray(y), lp_objective=lp_value)


def _check_lp_solver(lp_solver: str) -> None:
    if lp_solver not in LP_SOLVERS:
        raise SolverInputError(f"lp_solver={lp_solver!r} is not allowed; allowed: {', '.join(LP_SOLVERS)}")


def solve_ufl(fixed_cost: Any, cost: Any, method: str = "milp", lp_solver: str = "HIGHS",
              time_limit: float | None = None) -> SolveResult:
    """Uncapacitated facility location: ``fixed_cost`` (m,), ``cost`` (m, n) facility x client."""
    check_method(method, METHODS, "wfbench.solvers.facility_location.solve_ufl")
    _check_lp_solver(lp_solver)
    time_limit = check_time_limit(time_limit)
    C = as_matrix(cost, "cost")
    m, n = C.shape
    if m == 0 or n == 0:
        raise SolverInputError(f"cost has shape {C.shape}; UFL needs at least one facility and one client")
    f = as_vector(fixed_cost, "fixed_cost", m)
    return _solve(C, f, 0, method, lp_solver, time_limit, "solve_ufl")


def solve_p_median(dist: Any, p: int, method: str = "milp", weights: Any = None, lp_solver: str = "HIGHS",
                   time_limit: float | None = None) -> SolveResult:
    """p-median: ``dist`` (m candidates, n clients), open exactly ``p`` candidates.

    ``weights`` (n,), default all 1, scale each client's distance (demand weights).
    """
    check_method(method, METHODS, "wfbench.solvers.facility_location.solve_p_median")
    _check_lp_solver(lp_solver)
    time_limit = check_time_limit(time_limit)
    D = as_matrix(dist, "dist")
    m, n = D.shape
    if n == 0:
        raise SolverInputError(f"dist has shape {D.shape}; p-median needs at least one client")
    if isinstance(p, bool) or not isinstance(p, int | np.integer) or not 1 <= p <= m:
        raise SolverInputError(f"p = {p!r} is not allowed; allowed: an integer with 1 <= p <= {m} (the candidates)")
    C = D if weights is None else D * as_vector(weights, "weights", n, nonneg=True)[None, :]
    return _solve(C, np.zeros(m), int(p), method, lp_solver, time_limit, "solve_p_median")
