"""Solver-backed decisions that call :mod:`solvers` from Python, one environment at a time.

:class:`AssignmentDispatch` solves the compiled ``assignment`` dispatch's problem, with the same
costs, through :func:`wfbench.solvers.assignment.solve`, so the exact, MILP and LP methods can be
compared inside the simulator (``assignment-scipy``, ``-milp``, ``-lp``, ``-lp-osqp``; a test
checks that they agree on the total cost). Every solve has a stated time limit,
``time_limit_s`` (:data:`DEFAULT_TIME_LIMIT_S`), recorded by the leaderboard. ``docs/solvers.md``,
"Solver-backed policies" and "Time limits".
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.protocol import as_obs, hp_vector, seeds_array
from wfbench.solvers import assignment

DEFAULT_TIME_LIMIT_S = 1.0  # per solve: the dispatch problems here take milliseconds (docs/solvers.md, "Time limits")


class AssignmentDispatch:
    """Optimal-assignment dispatch through :func:`wfbench.solvers.assignment.solve`.

    ``method``: ``"exact"`` (scipy), ``"milp"`` (HiGHS) or ``"lp"`` (cvxpy with
    ``lp_solver`` HIGHS or OSQP), each solve limited to ``time_limit_s`` seconds.
    Hyper-parameters as for the compiled ``assignment`` dispatch (``speed``, ``fix_*``,
    ``revisit_cost``, ``unassigned_cost``).
    """

    decisions = ("dispatch",)

    def __init__(self, method: str = "exact", lp_solver: str = "HIGHS", name: str | None = None,
                 time_limit_s: float = DEFAULT_TIME_LIMIT_S, **hp: float):
        if method not in assignment.METHODS:
            raise ValueError(f"method={method!r} is not allowed; allowed: {', '.join(assignment.METHODS)}")
        if isinstance(time_limit_s, bool) or not isinstance(time_limit_s, int | float) or not time_limit_s > 0:
            raise ValueError(f"time_limit_s={time_limit_s!r} is not allowed; allowed: seconds > 0")
        self.name = name or f"assignment-{method}"
        self.hp = hp_vector(hp, self.name)
        self.method = method
        self.lp_solver = lp_solver
        # exact (scipy) is polynomial and has no limit to state
        self.time_limit_s = None if method == "exact" else float(time_limit_s)
        self.solve_time_s = 0.0  # total time inside the solver, for the benchmarks

    def __repr__(self) -> str:
        return (f"AssignmentDispatch(method={self.method!r}, lp_solver={self.lp_solver!r}, "
                f"time_limit_s={self.time_limit_s!r})")

    def reset(self, seeds: int | Sequence[int]) -> None:
        seeds_array(seeds)
        self.solve_time_s = 0.0

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        o = as_obs(obs)
        B, M = o.facilities.shape[:2]
        N = o.personnel.shape[1]
        out = np.full((B, M), N, dtype=np.int64)
        u = self.hp[K.HP_UNASSIGNED]
        for b in range(B):
            reqs, people = K.open_requests_and_free_people(b, o)
            if reqs.size == 0 or people.size == 0:
                continue
            C = K.assignment_costs(b, o, self.hp, reqs, people)
            res = assignment.solve(C, unassigned_cost=None if np.isinf(u) else u, method=self.method,
                                   lp_solver=self.lp_solver, time_limit=self.time_limit_s)
            if not res.has_solution:
                limit = " within its time limit (time_limit_s)" if res.status == "time_limit" else ""
                raise RuntimeError(f"{self!r}: the solver found no assignment{limit} ({res.status}: {res.message})")
            self.solve_time_s += res.solve_time_s
            rows = np.flatnonzero(res.solution >= 0)
            out[b, reqs[rows]] = people[res.solution[rows]]
        return {"dispatch": out}
