"""Rectangular min-cost assignment with forbidden pairs and an optional "leave unassigned" cost.

:func:`solve` minimizes ``sum_ij c_ij x_ij + sum_i u_i (1 - sum_j x_ij)`` over one-to-one pairs
the mask allows. Without ``unassigned_cost`` every row of the smaller side must be assigned
(scipy's convention; ``"infeasible"`` when the mask forbids it); with it any row may stay
unassigned at that cost. Methods ``"exact"`` (:func:`scipy.optimize.linear_sum_assignment`),
``"milp"`` (HiGHS) and ``"lp"`` (cvxpy, HiGHS or OSQP, built once per shape with Parameters)
agree on the optimum (tested). :func:`candidate_mask` and :func:`solve_sparse` are the reference
for the sparse assignment. How each method works: ``docs/solvers.md``, "Assignment".
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from wfbench.solvers.result import (
    EMPTY,
    FEASIBLE,
    INFEASIBLE,
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

METHODS = ("exact", "milp", "lp")
LP_SOLVERS = ("HIGHS", "OSQP")


def _inputs(cost: Any, mask: Any, unassigned_cost: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    if mask is None:
        C = as_matrix(cost, "cost")
        allowed = np.ones(C.shape, dtype=bool)
    else:
        allowed = np.asarray(mask)
        if allowed.dtype != bool:
            if not np.isin(allowed, (0, 1)).all():
                raise SolverInputError("mask must be boolean (True = allowed pair) or 0/1")
            allowed = allowed.astype(bool)
        C = np.array(cost, dtype=np.float64) if np.ndim(cost) == 2 else None
        if C is None or allowed.shape != C.shape:
            shape = None if C is None else C.shape
            raise SolverInputError(f"mask must have the shape of cost {shape}; got {allowed.shape}")
        C = as_matrix(cost, "cost", mask=allowed)
    u = None if unassigned_cost is None else as_vector(unassigned_cost, "unassigned_cost", C.shape[0])
    return C, allowed, u


def _objective(C: np.ndarray, u: np.ndarray | None, sol: np.ndarray) -> float:
    rows = np.flatnonzero(sol >= 0)
    total = float(C[rows, sol[rows]].sum()) if rows.size else 0.0
    if u is not None:
        total += float(u[sol < 0].sum())
    return total


def _infeasible(n: int, method: str, solver: str, seconds: float, message: str) -> SolveResult:
    return SolveResult(INFEASIBLE, math.nan, np.full(n, -1, dtype=np.int64), None, seconds, solver, method,
                       message=message)


_NOT_MATCHABLE = (
    "the mask leaves no assignment that covers every row of the smaller side; "
    "pass unassigned_cost to allow leaving rows unassigned"
)


def _exact(C: np.ndarray, allowed: np.ndarray, u: np.ndarray | None) -> np.ndarray | None:
    """Optimal row -> column (-1 unassigned), or None when infeasible."""
    # scipy.optimize is imported where it is used: the compiled policies import this
    # package and would otherwise pay ~0.4 s for it at start-up
    from scipy.optimize import linear_sum_assignment

    n, m = C.shape
    W = np.where(allowed, C, np.inf)
    if u is not None:
        dummy = np.full((n, n), np.inf)
        np.fill_diagonal(dummy, u)
        W = np.hstack([W, dummy])
    if not np.isfinite(W).any():
        if u is None and min(n, m) > 0:
            return None
        return np.full(n, -1, dtype=np.int64)
    try:
        r, c = linear_sum_assignment(W)
    except ValueError:
        return None
    sol = np.full(n, -1, dtype=np.int64)
    keep = c < m
    sol[r[keep]] = c[keep]
    return sol


def _milp(C, allowed, u, time_limit):
    import scipy.sparse as sp
    from scipy.optimize import LinearConstraint, milp

    n, m = C.shape
    ii, jj = np.nonzero(allowed)
    k = ii.size
    obj = C[ii, jj] - (u[ii] if u is not None else 0.0)
    const = float(u.sum()) if u is not None else 0.0
    A = sp.vstack([
        sp.csr_matrix((np.ones(k), (ii, np.arange(k))), shape=(n, k)),
        sp.csr_matrix((np.ones(k), (jj, np.arange(k))), shape=(m, k)),
    ]).tocsr()
    lb = np.zeros(n + m)
    if u is None:
        if n <= m:
            lb[:n] = 1.0
        else:
            lb[n:] = 1.0
    options = {"disp": False}
    if time_limit is not None:
        options["time_limit"] = time_limit
    with without_highs_stray():
        res = milp(obj, integrality=np.ones(k), bounds=(0, 1), constraints=LinearConstraint(A, lb, np.ones(n + m)),
                   options=options)
    return res, ii, jj, const


def _lp_round(C, allowed, u, x):
    """An integral assignment from an optimal LP solution (see the module docstring)."""
    support = allowed & (x > 1e-6)
    sol = _exact(C, support, u)
    if sol is not None:
        return sol, "support"
    # the assignment that keeps the most LP mass: leaving row i open "keeps" 1 - sum_j x_ij
    sol = _exact(-x, allowed, None if u is None else -(1.0 - x.sum(axis=1)))
    if sol is None:  # the LP was feasible, so the allowed pairs do admit an assignment
        raise RuntimeError("LP rounding found no assignment on pairs the LP called feasible")
    return sol, "max-mass"


class AssignmentLP:
    """The LP relaxation of one problem shape, built once with cvxpy Parameters.

    ``solve`` sets the parameters and re-solves; cvxpy reuses the compiled problem
    (DPP), so only the first solve of a shape pays the compilation.
    """

    def __init__(self, n: int, m: int, with_unassigned: bool, lp_solver: str = "HIGHS",
                 data: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None):
        import cvxpy as cp

        self.shape = (n, m)
        self.with_unassigned = with_unassigned
        self.lp_solver = lp_solver
        self.parametric = data is None
        if self.parametric:
            self.cost = cp.Parameter((n, m), name="cost")
            self.allowed = cp.Parameter((n, m), nonneg=True, name="allowed")
        else:  # one-off problem with the data as constants (see PARAMETRIC_MAX_PAIRS)
            C, allowed, u = data
            self.cost = cp.Constant(np.where(allowed, C, 0.0))
            self.allowed = cp.Constant(allowed.astype(np.float64))
        self.x = cp.Variable((n, m), nonneg=True)
        obj = cp.sum(cp.multiply(self.cost, self.x))
        rows = cp.sum(self.x, axis=1)
        cols = cp.sum(self.x, axis=0)
        cons = [self.x <= self.allowed]
        if with_unassigned:
            self.u = cp.Parameter(n, name="unassigned_cost") if self.parametric else cp.Constant(data[2])
            obj = obj + cp.sum(self.u) - self.u @ rows
            cons += [rows <= 1, cols <= 1]
        elif n <= m:
            cons += [rows == 1, cols <= 1]
        else:
            cons += [rows <= 1, cols == 1]
        self.problem = cp.Problem(cp.Minimize(obj), cons)
        self.solves = 0

    def solve(self, C: np.ndarray, allowed: np.ndarray, u: np.ndarray | None, time_limit: float | None = None):
        import cvxpy as cp

        if self.parametric:
            self.cost.value = np.where(allowed, C, 0.0)
            self.allowed.value = allowed.astype(np.float64)
            if self.with_unassigned:
                self.u.value = u
        kwargs: dict[str, Any] = {}
        if self.lp_solver == "OSQP":
            kwargs = {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iter": 100_000, **OSQP_POLISH}
            if time_limit is not None:
                kwargs["time_limit"] = time_limit
        elif time_limit is not None:
            kwargs["time_limit"] = time_limit
        rebuilt = self.solves == 0
        try:
            with warnings.catch_warnings():
                # an inaccurate solve shows in the status ("optimal_inaccurate"), which we report
                warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
                self.problem.solve(solver=getattr(cp, self.lp_solver), warm_start=True, **kwargs)
        except cp.error.SolverError as exc:
            return None, f"{self.lp_solver} failed: {exc}", rebuilt
        self.solves += 1
        return self.problem, self.problem.status, rebuilt


_LP_CACHE: dict[tuple[int, int, bool, str], AssignmentLP] = {}

# Above this many pairs the LP is built with its data as constants, once per solve: cvxpy's
# parametric (DPP) form keeps a parameter-to-problem map whose size grows with the square
# of the number of pairs (about 62 billion entries at 500 x 500).
PARAMETRIC_MAX_PAIRS = 10_000


def lp_model(n: int, m: int, with_unassigned: bool, lp_solver: str) -> AssignmentLP:
    key = (n, m, with_unassigned, lp_solver)
    if key not in _LP_CACHE:
        _LP_CACHE[key] = AssignmentLP(n, m, with_unassigned, lp_solver)
    return _LP_CACHE[key]


def solve(
    cost: Any,
    mask: Any = None,
    unassigned_cost: Any = None,
    method: str = "exact",
    lp_solver: str = "HIGHS",
    time_limit: float | None = None,
) -> SolveResult:
    """Min-cost assignment; ``solution[i]`` is row i's column, -1 if unassigned.

    ``cost`` is ``(n_rows, n_cols)``; ``mask`` (same shape, True = allowed) forbids
    pairs (their cost may then be anything, NaN included); ``unassigned_cost`` lets
    rows stay unassigned at that cost. See the module docstring for the methods.
    """
    check_method(method, METHODS, "wfbench.solvers.assignment.solve")
    if lp_solver not in LP_SOLVERS:
        raise SolverInputError(f"lp_solver={lp_solver!r} is not allowed; allowed: {', '.join(LP_SOLVERS)}")
    time_limit = check_time_limit(time_limit)
    C, allowed, u = _inputs(cost, mask, unassigned_cost)
    n, m = C.shape
    solver = {"exact": "scipy.linear_sum_assignment", "milp": "HiGHS (scipy.milp)", "lp": f"cvxpy/{lp_solver}"}[method]
    with Timer() as clock:
        if n == 0 or (m == 0 and u is None):
            sol = np.full(n, -1, dtype=np.int64)
            return SolveResult(EMPTY, 0.0, sol, 0.0, clock.elapsed, solver, method, gap=0.0,
                               message="nothing to assign")
        if method == "exact":
            sol = _exact(C, allowed, u)
            if sol is None:
                return _infeasible(n, method, solver, clock.elapsed, _NOT_MATCHABLE)
            obj = _objective(C, u, sol)
            return SolveResult(OPTIMAL, obj, sol, obj, clock.elapsed, solver, method, gap=0.0)
        if method == "milp" and not allowed.any():
            if u is None:
                return _infeasible(n, method, solver, clock.elapsed, _NOT_MATCHABLE)
            sol = np.full(n, -1, dtype=np.int64)
            obj = _objective(C, u, sol)
            return SolveResult(OPTIMAL, obj, sol, obj, clock.elapsed, solver, method, gap=0.0,
                               message="every pair is forbidden: every row unassigned")
        if method == "milp":
            res, ii, jj, const = _milp(C, allowed, u, time_limit)
            if res.status == 2:
                return _infeasible(n, method, solver, clock.elapsed, _NOT_MATCHABLE)
            if res.x is None:
                status = TIME_LIMIT if res.status == 1 else INFEASIBLE
                return SolveResult(status, math.nan, np.full(n, -1, dtype=np.int64), None, clock.elapsed, solver,
                                   method, message=f"HiGHS found no solution: {res.message}")
            sol = np.full(n, -1, dtype=np.int64)
            chosen = res.x > 0.5
            sol[ii[chosen]] = jj[chosen]
            obj = _objective(C, u, sol)
            bound = getattr(res, "mip_dual_bound", None)
            bound = obj if bound is None or res.status == 0 else float(bound) + const
            status = OPTIMAL if res.status == 0 else TIME_LIMIT
            return SolveResult(status, obj, sol, bound, clock.elapsed, solver, method, gap=relative_gap(obj, bound),
                               message=str(res.message))
        # LP relaxation
        if m == 0:  # everything unassigned; cvxpy cannot build a 0-column variable
            sol = np.full(n, -1, dtype=np.int64)
            obj = _objective(C, u, sol)
            return SolveResult(OPTIMAL, obj, sol, obj, clock.elapsed, solver, method, gap=0.0)
        if n * m <= PARAMETRIC_MAX_PAIRS:
            model = lp_model(n, m, u is not None, lp_solver)
        else:
            model = AssignmentLP(n, m, u is not None, lp_solver, data=(C, allowed, u))
        problem, status, rebuilt = model.solve(C, allowed, u, time_limit)
        if problem is None:
            return SolveResult(INFEASIBLE, math.nan, np.full(n, -1, dtype=np.int64), None, clock.elapsed, solver,
                               method, message=status, detail={"rebuilt": rebuilt})
        if status in ("infeasible", "infeasible_inaccurate"):
            return _infeasible(n, method, solver, clock.elapsed, _NOT_MATCHABLE)
        if model.x.value is None:
            return SolveResult(TIME_LIMIT, math.nan, np.full(n, -1, dtype=np.int64), None, clock.elapsed, solver,
                               method, message=f"{lp_solver} returned no solution (status {status})",
                               detail={"rebuilt": rebuilt})
        x = np.asarray(model.x.value)
        sol, how = _lp_round(C, allowed, u, x)
        obj = _objective(C, u, sol)
        lp_value = float(problem.value)
        # HiGHS solves the LP to optimality (a bound); OSQP's first-order answer is only close
        bound = lp_value if lp_solver == "HIGHS" and status == "optimal" else None
        # the polytope is integral: the rounding of an optimal LP solution meets its value
        proven = bound is not None and obj <= bound + 1e-9 * max(1.0, abs(bound))
        return SolveResult(
            OPTIMAL if proven else FEASIBLE, obj, sol, bound, clock.elapsed, solver, method,
            gap=relative_gap(obj, bound), message=f"LP status {status}; rounding: {how}",
            detail={"rebuilt": rebuilt, "lp_objective": lp_value, "lp_solution": x},
        )


def candidate_mask(distance: Any, k: int) -> np.ndarray:
    """Each row's ``k`` nearest columns by ``distance`` (ties to the lower column): the sparse candidate graph.

    The plain reference of the compiled rule ``assignment-sparse``
    (:func:`wfbench.solvers.lap.knn_manhattan`, docs/solvers.md "Sparse candidate graphs").
    """
    D = as_matrix(distance, "distance")
    if isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 1:
        raise SolverInputError(f"k = {k!r} is not allowed; allowed: an integer >= 1")
    n, m = D.shape
    mask = np.zeros((n, m), dtype=bool)
    if m:
        order = np.argsort(D, axis=1, kind="stable")[:, :k]
        mask[np.arange(n)[:, None], order] = True
    return mask


def solve_sparse(cost: Any, candidates: Any, unassigned_cost: Any = None) -> SolveResult:
    """Min-cost assignment on a candidate graph, every row allowed "nobody": the reference of ``lap_sparse``.

    ``candidates`` (the shape of ``cost``, True = an edge) is usually :func:`candidate_mask`.
    With ``unassigned_cost`` a row is left unassigned at that cost; without it, at a cost
    above any assignment's total, so the optimum serves as many rows as the graph allows,
    then at the least cost (the dense rule's "as many as possible"). Exact on the graph
    (scipy); its objective counts only the pairs made and the given unassigned costs.
    """
    C, allowed, u = _inputs(cost, candidates, unassigned_cost)
    n, m = C.shape
    big = None
    if u is None:
        top = np.where(allowed, C, -np.inf).max(axis=1, initial=0.0) if m else np.zeros(n)
        big = np.full(n, 1.0 + np.abs(top).sum())
    with Timer() as clock:
        sol = _exact(C, allowed, u if u is not None else big)
        obj = _objective(C, u, sol)
    return SolveResult(OPTIMAL, obj, sol, obj, clock.elapsed, "scipy.linear_sum_assignment", "exact", gap=0.0,
                       message=f"{int((sol >= 0).sum())} of {n} rows assigned on the candidate graph")
