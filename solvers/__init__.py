"""Pure optimization for workforce problems: arrays in, :class:`SolveResult` out.

- :mod:`solvers.assignment` min-cost rectangular assignment (exact, MILP, LP relaxation);
- :mod:`solvers.facility_location` uncapacitated facility location and p-median (MILP,
  LP relaxation with rounding, greedy + local search);
- :mod:`solvers.staffing` Erlang C and square-root staffing;
- :mod:`solvers.orlib` readers for the OR-Library instance formats.

Nothing here imports the simulator or any other package of ours (``docs/design.md``, layers).
"""

from solvers.result import SolveResult, SolverInputError

__all__ = ["SolveResult", "SolverInputError"]
