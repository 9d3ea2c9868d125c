"""The one result type every solver returns, the input checks they share, and HiGHS's stray output.

``solvers`` is pure optimization: arrays in, :class:`SolveResult` out. It imports
nothing of the simulator, so OR users can take it alone.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Statuses, from best to worst.
OPTIMAL = "optimal"  # proven optimal (exact methods; the LP when its rounding meets the bound)
FEASIBLE = "feasible"  # a solution without a proof of optimality (heuristics, LP rounding)
TIME_LIMIT = "time_limit"  # stopped by the time limit: best solution found, with its gap
INFEASIBLE = "infeasible"  # no solution satisfies the constraints
EMPTY = "empty"  # nothing to decide (a 0 x n problem): the empty solution, objective 0
STATUSES = (OPTIMAL, FEASIBLE, TIME_LIMIT, INFEASIBLE, EMPTY)


def _osqp_polish_option() -> dict[str, bool]:
    """OSQP 1.x renamed ``polish`` to ``polishing``."""
    try:
        from importlib.metadata import version

        major = int(version("osqp").split(".")[0])
    except Exception:  # noqa: BLE001 - osqp missing or unparsable: the old name
        major = 0
    return {"polishing": True} if major >= 1 else {"polish": True}


OSQP_POLISH = _osqp_polish_option()


class SolverInputError(ValueError):
    """The input cannot describe a problem: wrong shape, NaN or infinite costs, bad p."""


@dataclass(frozen=True)
class SolveResult:
    """Outcome of one solve.

    ``solution`` depends on the problem: for assignment, the column assigned to each
    row (-1 unassigned); for facility location and p-median, the sorted indices of the
    open facilities (``detail["assignment"]`` holds each client's facility).
    ``bound`` is a proven lower bound on the optimum where the method has one (MILP
    dual bound, LP relaxation value), else ``None``; ``gap`` is
    ``(objective - bound) / max(1, |objective|)``.
    """

    status: str
    objective: float
    solution: np.ndarray
    bound: float | None
    solve_time_s: float
    solver: str
    method: str
    gap: float | None = None
    message: str = ""
    detail: Mapping[str, Any] = field(default_factory=dict)

    @property
    def has_solution(self) -> bool:
        return self.status in (OPTIMAL, FEASIBLE, TIME_LIMIT, EMPTY)

    def __repr__(self) -> str:
        bound = "None" if self.bound is None else f"{self.bound:.6g}"
        gap = "None" if self.gap is None else f"{self.gap:.3g}"
        return (
            f"SolveResult(status={self.status!r}, objective={self.objective:.6g}, bound={bound}, gap={gap}, "
            f"solver={self.solver!r}, method={self.method!r}, solve_time_s={self.solve_time_s:.4f})"
        )


def relative_gap(objective: float, bound: float | None) -> float | None:
    if bound is None or not math.isfinite(objective) or not math.isfinite(bound):
        return None
    return max(0.0, (objective - bound) / max(1.0, abs(objective)))


class Timer:
    def __enter__(self) -> Timer:
        self.t0 = time.perf_counter()
        return self

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def __exit__(self, *exc: object) -> None:
        pass


def check_method(method: str, allowed: tuple[str, ...], what: str) -> None:
    if method not in allowed:
        raise SolverInputError(f"{what}: method={method!r} is not allowed; allowed: {', '.join(allowed)}")


def as_matrix(a: Any, name: str, mask: np.ndarray | None = None) -> np.ndarray:
    """A 2-D float64 copy of ``a`` whose entries (where ``mask`` allows) are finite."""
    try:
        m = np.array(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SolverInputError(f"{name} must be a 2-D array of numbers: {exc}") from None
    if m.ndim != 2:
        raise SolverInputError(f"{name} must be 2-D; got shape {m.shape}")
    bad = ~np.isfinite(m)
    if mask is not None:
        bad &= mask
    if bad.any():
        i, j = np.argwhere(bad)[0]
        where = " at an allowed pair" if mask is not None else ""
        raise SolverInputError(
            f"{name}[{i}, {j}] = {m[i, j]} is not allowed{where}: costs must be finite "
            f"({int(bad.sum())} bad entr{'y' if bad.sum() == 1 else 'ies'}); forbid a pair with the mask instead"
        )
    return m


def as_vector(a: Any, name: str, n: int, *, nonneg: bool = False) -> np.ndarray:
    try:
        v = np.array(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SolverInputError(f"{name} must be numbers: {exc}") from None
    if v.ndim == 0:
        v = np.full(n, float(v))
    if v.shape != (n,):
        raise SolverInputError(f"{name} must be a scalar or have shape ({n},); got shape {v.shape}")
    if not np.isfinite(v).all():
        i = int(np.flatnonzero(~np.isfinite(v))[0])
        raise SolverInputError(f"{name}[{i}] = {v[i]} is not allowed: values must be finite")
    if nonneg and (v < 0).any():
        i = int(np.flatnonzero(v < 0)[0])
        raise SolverInputError(f"{name}[{i}] = {v[i]} is not allowed: values must be >= 0")
    return v


def check_time_limit(time_limit: float | None) -> float | None:
    if time_limit is None:
        return None
    if not (isinstance(time_limit, int | float) and math.isfinite(time_limit) and time_limit > 0):
        raise SolverInputError(f"time_limit = {time_limit!r} is not allowed; allowed: a number of seconds > 0, or None")
    return float(time_limit)


# HiGHS (the copy inside scipy) prints this line with C's printf, past its own output_flag, when it repairs an
# incumbent (ERGO-Code/HiGHS#2783): it reaches the user's terminal and logs in the middle of wfbench's output
HIGHS_STRAY = b"HighsMipSolverData::transformNewIntegerFeasibleSolution tmpSolver.run();"
_stdout_lock = threading.Lock()
_stdout_users = 0
_stdout_saved: tuple[int, Any] | None = None  # the real stdout's duplicate, the capture file


@contextmanager
def without_highs_stray() -> Iterator[None]:
    """Run a HiGHS solve with the process's stdout (fd 1) caught, then pass on all but HiGHS's stray line.

    Whatever else reached fd 1 meanwhile (another thread's output) is written on to the
    real stdout when the last solve in flight ends: nothing is lost, only delayed. Threads
    share one capture (a count of the solves in flight).
    """
    global _stdout_users, _stdout_saved
    with _stdout_lock:
        if _stdout_users == 0:
            for stream in (sys.stdout, sys.__stdout__):
                if stream is not None:
                    try:
                        stream.flush()
                    except (OSError, ValueError):
                        pass
            try:
                capture = tempfile.TemporaryFile()
                real = os.dup(1)
                os.dup2(capture.fileno(), 1)
                _stdout_saved = (real, capture)
            except OSError:  # no stdout (fd 1 closed) or nowhere to write (a sandbox): the solve runs as it is
                _stdout_saved = None
        _stdout_users += 1
    try:
        yield
    finally:
        with _stdout_lock:
            _stdout_users -= 1
            if _stdout_users == 0 and _stdout_saved is not None:
                real, capture = _stdout_saved
                _stdout_saved = None
                os.dup2(real, 1)
                os.close(real)
                capture.seek(0)
                kept = b"".join(line for line in capture.read().splitlines(keepends=True)
                                if line.rstrip(b"\r\n") != HIGHS_STRAY)
                capture.close()
                while kept:
                    kept = kept[os.write(1, kept):]
