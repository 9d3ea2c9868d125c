"""The built-in decision rules in one table, and the hyper-parameters they read in another.

A row of :data:`RULES` is everything wfbench knows about a rule of :mod:`wfbench.policies.kernels`:
its decision, its name, its label in tables and the hyper-parameters a tuner may change; its
integer code is its position among its decision's rows (the no-op first, code 0).
:data:`HYPERPARAMETERS` lays out the flat vector ``hp`` every kernel reads at run time (so a
tuned value needs no recompile): each field's default and, where it may be searched, its range
(:class:`~wfbench.policies.tunable.Param`); the model-of-the-world fields have none. A new rule is
a row here, its kernel and the branch of ``act_rules`` that calls it. ``docs/policies.md``,
"Tuning".
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from wfbench.policies.tunable import Param


class HyperParameter(NamedTuple):
    """One field of the hyper-parameter vector ``hp``: its name, default and, if a tuner may change it, range."""

    name: str
    default: float
    range: Param | None = None  # None: not searched (a fact of the world, or a value no tuner should move)


_LEVEL = Param(0.0, 1.0)  # relative weight of a level
_SMOOTHING = Param(0.001, 0.5, log=True)

HYPERPARAMETERS: tuple[HyperParameter, ...] = (
    HyperParameter("high", 0.8, Param(0.3, 1.0)),  # threshold workforce: hire when utilization is above this
    HyperParameter("low", 0.45, Param(0.0, 0.9)),  # ... let go when below this
    HyperParameter("cooldown", 30.0, Param(1, 100, "int")),  # steps between two workforce actions
    HyperParameter("warmup", 50.0, Param(0, 200, "int")),  # no workforce action before this step
    # epsilon-greedy: probability of a random decision per step after the cooldown
    HyperParameter("epsilon", 0.02, Param(0.0, 0.5)),
    HyperParameter("p_novice", 0.25, _LEVEL),  # level draw of a hire (and of a let-go among the levels present)
    HyperParameter("p_mid", 0.5, _LEVEL),
    HyperParameter("p_expert", 0.25, _LEVEL),
    HyperParameter("smoothing", 0.01, _SMOOTHING),  # spatial positioning: weight of a new request in the average
    # ... share of the request history in a facility's demand (the rest: downtime)
    HyperParameter("request_weight", 0.5, Param(0.0, 1.0)),
    # Gaussian variant: standard deviation of the log-normal noise on the demand
    HyperParameter("noise", 0.5, Param(0.0, 2.0)),
    # the policies' model of the world (defaults: the paper's / paper-64's values)
    HyperParameter("speed", 1.0),  # cells a person moves per step
    HyperParameter("service_time", 3.0),  # steps a visit takes at the facility
    HyperParameter("fix_novice", 0.49),  # probability that a visit by each level fixes the fault
    HyperParameter("fix_mid", 0.70),
    HyperParameter("fix_expert", 0.84),
    # assignment dispatch: steps of downtime an unsuccessful visit adds (a new trip and service); chosen on
    # development seeds (docs/solvers.md; wfbench tune searches it now)
    HyperParameter("revisit_cost", 2.0, Param(0.0, 50.0)),
    # ... cost of leaving a request unassigned this step (inf: never, if someone is free)
    HyperParameter("unassigned_cost", np.inf),
    # staffing workforce: square-root staffing safety factor, c = R + beta sqrt(R); chosen on development
    # seeds: staff the offered load (docs/solvers.md)
    HyperParameter("beta", 0.0, Param(-1.0, 3.0)),
    # ... let go only when the headcount exceeds the target by more than this
    HyperParameter("hysteresis", 1.0, Param(0.0, 6.0)),
    HyperParameter("rate_smoothing", 0.01, _SMOOTHING),  # ... weight of a step in the average of the request rate
    # facility-location positioning: steps between two p-median solves (the maps are reused in between)
    HyperParameter("refresh", 10.0, Param(1, 100, "int")),
    # ... demand weight every active facility has, on top of its observed demand
    HyperParameter("demand_floor", 0.1, Param(0.0, 5.0)),
)
"""The fields of ``hp``, in its order (:data:`wfbench.policies.kernels.HP_FIELDS`)."""

HP_BY_NAME: dict[str, HyperParameter] = {h.name: h for h in HYPERPARAMETERS}


class Rule(NamedTuple):
    """One built-in decision rule: a compiled kernel, as every table, composite and tuner names it."""

    decision: str  # "dispatch", "workforce" or "positioning"
    name: str  # its name among the decision's built-in policies
    label: str  # how tables name it (Table 3's columns)
    tunes: tuple[str, ...] = ()  # the fields of HYPERPARAMETERS a tuner may change, in the search space's order

    @property
    def code(self) -> int:
        """What the compiled kernels dispatch on: the rule's position among its decision's rows (0: the no-op)."""
        return CODES[self.decision][self.name]

    @property
    def params(self) -> dict[str, Param]:
        """The tunable fields with their ranges (:class:`~wfbench.policies.tunable.Param`)."""
        return {f: HP_BY_NAME[f].range for f in self.tunes}


_THRESHOLD = ("high", "low", "cooldown", "warmup", "p_novice", "p_mid", "p_expert")
_SPATIAL = ("smoothing", "request_weight")

RULES: tuple[Rule, ...] = (
    Rule("dispatch", "none", "None"),
    Rule("dispatch", "nearest", "Heuristic"),
    Rule("dispatch", "inverse-distance", "Heuristic (stochastic)"),
    Rule("dispatch", "random", "Random"),
    Rule("dispatch", "assignment", "Assignment", ("revisit_cost",)),  # wfbench.solvers.lap
    # the same on each request's k nearest people (wfbench.solvers.lap; docs/solvers.md, "Sparse candidate graphs")
    Rule("dispatch", "assignment-sparse", "Assignment (sparse)", ("revisit_cost",)),
    Rule("workforce", "fixed", "Fixed"),
    Rule("workforce", "threshold", "Heuristic", _THRESHOLD),
    Rule("workforce", "threshold-epsilon", "Heuristic (stochastic)", (*_THRESHOLD, "epsilon")),
    Rule("workforce", "random", "Random"),
    Rule("workforce", "staffing", "Staffing",  # wfbench.solvers.staffing
         ("beta", "hysteresis", "rate_smoothing", "cooldown", "warmup", "p_novice", "p_mid", "p_expert")),
    Rule("positioning", "none", "None"),
    Rule("positioning", "spatial", "Heuristic", _SPATIAL),
    Rule("positioning", "spatial-gaussian", "Heuristic (stochastic)", (*_SPATIAL, "noise")),
    Rule("positioning", "random", "Random"),
    Rule("positioning", "facility-location", "p-median",  # wfbench.solvers.facility_location
         ("refresh", "demand_floor", *_SPATIAL)),
    Rule("positioning", "facility-location-sparse", "p-median (sparse)",  # ... on each client's k nearest sites
         ("refresh", "demand_floor", *_SPATIAL)),
)
"""The built-in rules: for each decision the no-op (code 0), then its rules in code order."""

CODES: dict[str, dict[str, int]] = {
    decision: {r.name: i for i, r in enumerate(r for r in RULES if r.decision == decision)}
    for decision in dict.fromkeys(r.decision for r in RULES)
}
"""Each rule's code by decision and name, as the compiled kernels dispatch on it."""


def code(decision: str, name: str) -> int:
    """The code of the rule ``name`` of ``decision`` (KeyError names the rules there are)."""
    try:
        return CODES[decision][name]
    except KeyError:
        raise KeyError(f"no built-in {decision} rule {name!r}; rules: {', '.join(CODES.get(decision, {}))}") from None
