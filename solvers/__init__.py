"""Pure optimization for workforce problems: arrays in, :class:`SolveResult` out.

- :mod:`wfbench.solvers.assignment` min-cost rectangular assignment (exact, MILP, LP relaxation);
- :mod:`wfbench.solvers.facility_location` uncapacitated facility location and p-median (MILP,
  LP relaxation with rounding, greedy + local search);
- :mod:`wfbench.solvers.staffing` Erlang C and square-root staffing;
- :mod:`wfbench.solvers.orlib` readers for the OR-Library instance formats.

Nothing here imports the simulator or any other package of ours (``docs/design.md``, layers).
"""

from wfbench.solvers.result import SolveResult, SolverInputError

__all__ = ["SolveResult", "SolverInputError"]
