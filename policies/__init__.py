"""Everything that decides: random, heuristics, and (later) solvers, oracles and RL."""

from policies.base import BuiltinDecision, Composite, Policy
from policies.registry import DECISIONS, get, names

__all__ = ["BuiltinDecision", "Composite", "DECISIONS", "Policy", "get", "names"]
