"""A rolling-horizon staffing plan: a MILP of hires and let-goes per level over the next H steps.

:func:`plan_staffing` plans one environment (a :class:`StaffingInstance`): hires ``x[l, h]`` and
let-goes ``y[l, h]`` (at most one action a step), with the hire and notice lags, a smallest
headcount, the slots as a cap on payroll, and forecast demand covered or paid for as shortfall;
it minimizes payroll plus the shortfall and action costs. With ``backlog0`` set (issue #53's second design)
the requests also form a fluid queue: they arrive per step, are served up to the productive people's
full rate (``service``; ``capacity`` is the rate at the target utilization, which coverage asks for),
and what is not served waits as backlog, from ``backlog0`` waiting now, priced per request a step.
Productive people and payroll are
variables with one balance row per step (sparse), solved by HiGHS through
:func:`scipy.optimize.milp` with an optional time or node limit (no incumbent yet: a plan of no
actions, always feasible). The model in full: ``docs/solvers.md``, "A rolling-horizon staffing plan".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from wfbench.solvers.result import (
    OPTIMAL,
    TIME_LIMIT,
    SolveResult,
    SolverInputError,
    Timer,
    check_time_limit,
    relative_gap,
    without_highs_stray,
)


@dataclass(frozen=True)
class StaffingInstance:
    """One plan's data; ``H`` steps, ``L`` levels (shapes checked by :func:`plan_staffing`)."""

    demand: np.ndarray  # (H,) demand per step
    capacity: np.ndarray  # (L,) demand one productive person of each level covers per step
    salary: np.ndarray  # (L,) pay per step
    ready: np.ndarray  # (L, H) productive people known now at each step (no decision of the plan)
    paid: np.ndarray  # (L, H) people on the payroll at each step, known now
    hire_delay: int
    notice_delay: int
    max_headcount: int
    min_headcount: int = 0
    shortfall_cost: float = 10.0
    action_cost: float = 1e-3
    # the fluid queue (issue #53): requests waiting now; None is the model without a queue (coverage or shortfall)
    backlog0: float | None = None
    backlog_cost: float = 0.0  # per request waiting per step (with backlog0), salary units
    service: np.ndarray | None = None  # (L,) requests a productive person serves a step at full rate; None: capacity


def _array(a: Any, name: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        v = np.array(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise SolverInputError(f"{name} must be numbers") from None
    if v.shape != shape:
        raise SolverInputError(f"{name} must have shape {shape}; got {v.shape}")
    if not np.isfinite(v).all() or (v < 0).any():
        raise SolverInputError(f"{name} must be finite numbers >= 0")
    return v


def _count(v: Any, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
        raise SolverInputError(f"{name} = {v!r} is not allowed; allowed: an integer >= 0")
    return int(v)


def plan_staffing(inst: StaffingInstance, time_limit: float | None = None, block: int = 1,
                  node_limit: int | None = None) -> SolveResult:
    """The optimal plan of ``inst`` (module docstring).

    ``node_limit``: HiGHS's branch-and-bound nodes at most (``mip_max_nodes``), a limit of
    work, not of time, so the plan is the same on any machine and under any load; a
    deployable policy limits its solves this way (``time_limit`` is wall-clock: the plan
    at the limit depends on the machine's speed).

    ``block``: decide once per ``block`` steps how many of each action the block takes (at
    most ``block``, one per step from its start), with the lags taken at their latest (a
    block's hires work from its last step plus ``hire_delay`` and are paid from its first;
    its let-goes stop work after its first step and are paid to its last plus
    ``notice_delay``). 1 is the exact per-step model; a larger block makes the MILP
    smaller (``2 L H / block`` integers) at the price of that pessimism.

    Returns:
        A :class:`SolveResult` whose ``solution`` is the (H,) workforce action per step in
        the simulator's coding (0 no-op, ``1 + l`` hire level l, ``1 + L + l`` let go level l);
        ``detail`` holds ``hires`` and ``letgo`` (L, blocks), ``productive`` and ``payroll``
        (L, H), ``coverage`` and ``shortfall`` (H,); with the queue (``backlog0`` set) also
        ``backlog`` (H,, the requests waiting after each step) and ``served`` (H,).
    """
    time_limit = check_time_limit(time_limit)
    if node_limit is not None and (isinstance(node_limit, bool) or not isinstance(node_limit, int) or node_limit < 1):
        raise SolverInputError(f"node_limit = {node_limit!r} is not allowed; allowed: an integer >= 1, or None")
    G = _count(block, "block")
    if G < 1:
        raise SolverInputError(f"block = {block!r} is not allowed; allowed: an integer >= 1")
    demand = np.atleast_1d(np.array(inst.demand, dtype=np.float64))
    H = demand.shape[0]
    if H < 1:
        raise SolverInputError("demand must have at least one step")
    demand = _array(demand, "demand", (H,))
    cap = np.atleast_1d(np.array(inst.capacity, dtype=np.float64))
    L = cap.shape[0]
    cap = _array(cap, "capacity", (L,))
    salary = _array(inst.salary, "salary", (L,))
    ready = _array(inst.ready, "ready", (L, H))
    paid = _array(inst.paid, "paid", (L, H))
    hd, nd = _count(inst.hire_delay, "hire_delay"), _count(inst.notice_delay, "notice_delay")
    max_head, min_head = _count(inst.max_headcount, "max_headcount"), _count(inst.min_headcount, "min_headcount")
    pen = float(inst.shortfall_cost)
    eps = float(inst.action_cost)
    if not (math.isfinite(pen) and pen >= 0 and math.isfinite(eps) and eps >= 0):
        raise SolverInputError("shortfall_cost and action_cost must be finite numbers >= 0")
    queue = inst.backlog0 is not None
    if queue:
        q0 = float(_array(inst.backlog0, "backlog0", ()))
        qc = inst.backlog_cost
        if isinstance(qc, bool) or not isinstance(qc, int | float | np.number) or not (math.isfinite(qc) and qc >= 0):
            raise SolverInputError(f"backlog_cost = {qc!r} is not allowed; allowed: a finite number >= 0")
        qc = float(qc)
        service = cap if inst.service is None else _array(inst.service, "service", (L,))
    with Timer() as clock:
        import scipy.sparse as sp
        from scipy.optimize import Bounds, LinearConstraint, milp

        G = block
        nk = -(-H // G)  # decision blocks
        nxy = L * nk
        # columns: x[l, k], y[l, k] (integers 0..G), then P[l, h], E[l, h] (continuous, integral at an optimum), s[h];
        # with the queue, q[h] the backlog after step h and u[h] the requests served in it follow
        X, Y, P, E, S = 0, nxy, 2 * nxy, 2 * nxy + L * H, 2 * nxy + 2 * L * H
        Q, U = S + H, S + 2 * H
        n = S + H + (2 * H if queue else 0)
        xk = lambda base, l, k: base + l * nk + k  # noqa: E731
        at = lambda base, l, h: base + l * H + h  # noqa: E731
        c = np.zeros(n)
        c[X:P] = eps
        for l in range(L):
            c[at(E, l, 0): at(E, l, 0) + H] = salary[l]
        c[S:S + H] = pen
        if queue:
            c[Q:U] = qc
        # where a block's decisions act: a hire works from k G + G - 1 + hire_delay and is paid from k G; a
        # let-go stops working at k G + 1 and is paid until k G + G - 1 + notice_delay (block 1: the exact lags)
        works, leaves, unpaid = {}, {}, {}
        for k in range(nk):
            works.setdefault(k * G + G - 1 + hd, []).append(k)
            leaves.setdefault(k * G + 1, []).append(k)
            unpaid.setdefault(k * G + G - 1 + nd, []).append(k)
        rows, cols, vals, lo, hi = [], [], [], [], []
        r = 0

        def add(entries, lower, upper):
            nonlocal r
            for j, v in entries:
                rows.append(r)
                cols.append(j)
                vals.append(v)
            lo.append(lower)
            hi.append(upper)
            r += 1

        floor = np.minimum(min_head, ready.sum(axis=0))
        for k in range(nk):  # at most one workforce action per step
            add([(xk(X, l, k), 1.0) for l in range(L)] + [(xk(Y, l, k), 1.0) for l in range(L)], -np.inf,
                min(G, H - k * G))
        for h in range(H):
            for l in range(L):
                # P[l, h] = P[l, h-1] + (ready[l, h] - ready[l, h-1]) + hires that start work - let-goes that stop
                e = [(at(P, l, h), 1.0)] + [(xk(X, l, k), -1.0) for k in works.get(h, ())]
                e += [(xk(Y, l, k), 1.0) for k in leaves.get(h, ())]
                if h > 0:
                    e.append((at(P, l, h - 1), -1.0))
                d = ready[l, h] - (ready[l, h - 1] if h > 0 else 0.0)
                add(e, d, d)
                # E[l, h] = E[l, h-1] + (paid[l, h] - paid[l, h-1]) + hires paid from h - notices that end
                e = [(at(E, l, h), 1.0)] + [(xk(X, l, k), -1.0) for k in ([h // G] if h % G == 0 else [])]
                e += [(xk(Y, l, k), 1.0) for k in unpaid.get(h, ())]
                if h > 0:
                    e.append((at(E, l, h - 1), -1.0))
                d = paid[l, h] - (paid[l, h - 1] if h > 0 else 0.0)
                add(e, d, d)
                if h % G == 0:  # a block's let-goes only of people productive at its start
                    add([(at(P, l, h), 1.0), (xk(Y, l, h // G), -1.0)], 0.0, np.inf)
            add([(at(P, l, h), cap[l]) for l in range(L)] + [(S + h, 1.0)], demand[h], np.inf)  # coverage
            if queue:  # served at most the people's full rate; backlog[h] = backlog[h-1] + arrivals - served
                add([(at(P, l, h), service[l]) for l in range(L)] + [(U + h, -1.0)], 0.0, np.inf)
                e = [(Q + h, 1.0), (U + h, 1.0)] + ([(Q + h - 1, -1.0)] if h > 0 else [])
                add(e, demand[h] + (q0 if h == 0 else 0.0), demand[h] + (q0 if h == 0 else 0.0))
            add([(at(P, l, h), 1.0) for l in range(L)], floor[h], np.inf)  # the smallest headcount
            add([(at(E, l, h), 1.0) for l in range(L)], -np.inf, max_head)  # the slots
        A = sp.csr_matrix((vals, (rows, cols)), shape=(r, n))
        integrality = np.concatenate([np.ones(2 * nxy), np.zeros(n - 2 * nxy)])
        upper = np.concatenate([np.full(2 * nxy, float(G)), np.full(n - 2 * nxy, np.inf)])
        options: dict[str, Any] = {"disp": False}
        if time_limit is not None:
            options["time_limit"] = time_limit
        if node_limit is not None:
            options["node_limit"] = node_limit
        with without_highs_stray():
            res = milp(c, integrality=integrality, bounds=Bounds(np.zeros(n), upper),
                       constraints=[LinearConstraint(A, np.asarray(lo), np.asarray(hi))], options=options)
    if res.x is None:
        if res.status == 1:  # a limit (time or nodes) before an incumbent: no actions (always feasible)
            z = np.zeros(n)
            z[P:E], z[E:S] = ready.ravel(), paid.ravel()
            z[S:S + H] = np.maximum(0.0, demand - cap @ ready)
            if queue:  # the queue under the no-action plan: serve what the people can
                q = q0
                for h in range(H):
                    z[U + h] = min(float(service @ ready[:, h]), q + demand[h])
                    q = z[Q + h] = q + demand[h] - z[U + h]
            return _result(TIME_LIMIT, z, c, None, clock.elapsed, L, H, G, cap,
                           "a limit before HiGHS found an incumbent; the plan of no actions", queue)
        raise RuntimeError(f"plan_staffing: HiGHS reports {res.message!r} on a problem the no-action plan satisfies "
                           "(check ready >= floor and paid <= max_headcount)")
    bound = getattr(res, "mip_dual_bound", None)
    bound = None if bound is None or not math.isfinite(bound) else float(bound)
    status = OPTIMAL if res.status == 0 else TIME_LIMIT
    return _result(status, res.x, c, bound, clock.elapsed, L, H, G, cap, str(res.message), queue)


def _result(status, z, c, bound, elapsed, L, H, G, cap, message, queue=False) -> SolveResult:
    nk = -(-H // G)
    nxy = L * nk
    x = np.rint(z[:nxy]).reshape(L, nk).astype(np.int64)
    y = np.rint(z[nxy:2 * nxy]).reshape(L, nk).astype(np.int64)
    P0 = 2 * nxy
    productive = np.rint(z[P0:P0 + L * H]).reshape(L, H)
    payroll = np.rint(z[P0 + L * H:P0 + 2 * L * H]).reshape(L, H)
    s = np.maximum(np.asarray(z[P0 + 2 * L * H:P0 + 2 * L * H + H], dtype=np.float64), 0.0)
    action = np.zeros(H, dtype=np.int64)
    for k in range(nk):  # a block's actions on its first steps: hires, then let-goes
        todo = [1 + l for l in range(L) for _ in range(x[l, k])] + [1 + L + l for l in range(L) for _ in range(y[l, k])]
        action[k * G: k * G + len(todo)] = todo
    objective = float(c @ z)
    detail = {"hires": x, "letgo": y, "productive": productive, "payroll": payroll,
              "shortfall": s, "coverage": cap @ productive, "block": G}
    if queue:  # the backlog after each step and the requests served in it follow the shortfall
        Q0 = P0 + 2 * L * H + H
        detail["backlog"] = np.maximum(np.asarray(z[Q0:Q0 + H], dtype=np.float64), 0.0)
        detail["served"] = np.maximum(np.asarray(z[Q0 + H:Q0 + 2 * H], dtype=np.float64), 0.0)
    return SolveResult(status=status, objective=objective, solution=action, bound=bound, solve_time_s=elapsed,
                       solver="highs", method="milp", gap=relative_gap(objective, bound), message=message,
                       detail=detail)


__all__ = ["StaffingInstance", "plan_staffing"]
