"""The built-in policies of each decision, by name: compiled kernels and solver-backed ones.

``DECISIONS[decision][name]()`` makes a fresh policy for that one decision; a composite
takes these names (``Composite("nearest", "threshold", "spatial")``) and
``wfbench policies`` lists them. Both tables here are made from two others: every rule
of :data:`wfbench.policies.rules.RULES` (a compiled kernel: its name, code and label),
then :data:`OTHERS`, the decisions that are not compiled rules.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any, NamedTuple

from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.rules import RULES
from wfbench.policies.solver import AssignmentDispatch

from wfbench.core.actions import AGENTS


def _oracle(cls: str) -> Callable[[], Any]:
    """The maker of the hindsight oracle ``cls`` of :mod:`wfbench.policies.oracle`, imported when one is made.

    Imported late so that a composite's import closure, which decides its episodes
    (:func:`wfbench.policies.oracle.episodes.decisive_files`), holds no oracle module.
    """

    def make() -> Any:
        from wfbench.policies import oracle

        return getattr(oracle, cls)()

    return make


class Other(NamedTuple):
    """A built-in decision policy that is not a compiled rule: how to make it, and how tables name it."""

    decision: str
    name: str
    label: str
    make: Callable[[], Any]


OTHERS: tuple[Other, ...] = (
    Other("dispatch", "assignment-scipy", "Assignment", lambda: AssignmentDispatch("exact", name="assignment-scipy")),
    Other("dispatch", "assignment-milp", "Assignment", lambda: AssignmentDispatch("milp", name="assignment-milp")),
    Other("dispatch", "assignment-lp", "Assignment", lambda: AssignmentDispatch("lp", "HIGHS", name="assignment-lp")),
    Other("dispatch", "assignment-lp-osqp", "Assignment",
          lambda: AssignmentDispatch("lp", "OSQP", name="assignment-lp-osqp")),
    # the oracles read the trace: not deployable (docs/hindsight.md)
    Other("dispatch", "oracle", "Hindsight oracle", _oracle("OracleDispatch")),
    Other("workforce", "oracle", "Hindsight oracle", _oracle("OracleWorkforce")),
    Other("positioning", "oracle", "Hindsight oracle", _oracle("OraclePositioning")),
)
"""The solver-backed dispatch policies (:mod:`wfbench.policies.solver`) and the hindsight oracles."""

_ALL = (*((r.decision, r.name, r.label, partial(BuiltinDecision, r.decision, r.code, r.name)) for r in RULES),
        *OTHERS)

DECISIONS: dict[str, dict[str, Callable[[], Any]]] = {
    decision: {name: make for d, name, _, make in _ALL if d == decision} for decision in AGENTS
}
"""Every built-in policy of each decision by name: the compiled rules in code order (no-op first), then the others."""

# How tables name each built-in decision (the columns of Table 3: the paper's "Random" and "Heuristic",
# wfbench's "Assignment", "Staffing", "p-median" and "Hindsight oracle"); :func:`label` falls back to the name.
LABELS: dict[str, dict[str, str]] = {
    decision: {name: text for d, name, text, _ in _ALL if d == decision} for decision in AGENTS
}


def label(decision: str, name: str) -> str:
    """How tables name the built-in policy ``name`` of ``decision`` (the name itself if it has no label)."""
    return LABELS.get(decision, {}).get(name, name)
