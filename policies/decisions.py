"""The built-in policies of each decision, by name: compiled kernels and solver-backed ones.

``DECISIONS[decision][name]()`` makes a fresh policy for that one decision; a composite
takes these names (``Composite("nearest", "threshold", "spatial")``) and
``wfbench policies`` lists them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from wfbench.policies import kernels as K
from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.oracle import OracleDispatch, OraclePositioning, OracleWorkforce
from wfbench.policies.solver import AssignmentDispatch


def _d(decision: str, code: int, name: str, **hp: float) -> Callable[[], BuiltinDecision]:
    return lambda: BuiltinDecision(decision, code, name, **hp)


DECISIONS: dict[str, dict[str, Callable[[], Any]]] = {
    "dispatch": {
        "nearest": _d("dispatch", K.D_NEAREST, "nearest"),
        "inverse-distance": _d("dispatch", K.D_INVERSE, "inverse-distance"),
        "random": _d("dispatch", K.D_RANDOM, "random"),
        "assignment": _d("dispatch", K.D_ASSIGN, "assignment"),
        "assignment-scipy": lambda: AssignmentDispatch("exact", name="assignment-scipy"),
        "assignment-milp": lambda: AssignmentDispatch("milp", name="assignment-milp"),
        "assignment-lp": lambda: AssignmentDispatch("lp", "HIGHS", name="assignment-lp"),
        "assignment-lp-osqp": lambda: AssignmentDispatch("lp", "OSQP", name="assignment-lp-osqp"),
        "none": _d("dispatch", K.D_NOOP, "none"),
        "oracle": OracleDispatch,  # reads the trace: not deployable (docs/hindsight.md)
    },
    "workforce": {
        "threshold": _d("workforce", K.W_THRESHOLD, "threshold"),
        "threshold-epsilon": _d("workforce", K.W_EPSILON, "threshold-epsilon"),
        "random": _d("workforce", K.W_RANDOM, "random"),
        "staffing": _d("workforce", K.W_STAFFING, "staffing"),
        "fixed": _d("workforce", K.W_NOOP, "fixed"),
        "oracle": OracleWorkforce,  # reads the trace: not deployable
    },
    "positioning": {
        "spatial": _d("positioning", K.P_SPATIAL, "spatial"),
        "spatial-gaussian": _d("positioning", K.P_GAUSSIAN, "spatial-gaussian"),
        "random": _d("positioning", K.P_RANDOM, "random"),
        "facility-location": _d("positioning", K.P_FACILITY, "facility-location"),
        "none": _d("positioning", K.P_NONE, "none"),
        "oracle": OraclePositioning,  # reads the trace: not deployable
    },
}

# How tables name each built-in decision (the columns of Table 3: the paper's "Random" and "Heuristic",
# wfbench's "Assignment", "Staffing", "p-median" and "Hindsight oracle"); :func:`label` falls back to the name.
LABELS: dict[str, dict[str, str]] = {
    "dispatch": {"nearest": "Heuristic", "inverse-distance": "Heuristic (stochastic)", "random": "Random",
                 "assignment": "Assignment", "assignment-scipy": "Assignment", "assignment-milp": "Assignment",
                 "assignment-lp": "Assignment", "assignment-lp-osqp": "Assignment", "none": "None",
                 "oracle": "Hindsight oracle"},
    "workforce": {"threshold": "Heuristic", "threshold-epsilon": "Heuristic (stochastic)", "random": "Random",
                  "staffing": "Staffing", "fixed": "Fixed", "oracle": "Hindsight oracle"},
    "positioning": {"spatial": "Heuristic", "spatial-gaussian": "Heuristic (stochastic)", "random": "Random",
                    "facility-location": "p-median", "none": "None", "oracle": "Hindsight oracle"},
}


def label(decision: str, name: str) -> str:
    """How tables name the built-in policy ``name`` of ``decision`` (the name itself if it has no label)."""
    return LABELS.get(decision, {}).get(name, name)
