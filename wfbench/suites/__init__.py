"""Scenario suites: a versioned set of scenarios with a training and a held-out split, and the normalized score.

A suite is data: each scenario is a preset plus a version (its id is ``<preset>-v<version>``,
e.g. ``paper-64-v1``), the split it belongs to and why it is there. ``train`` scenarios
may be tuned and trained on (public seeds 1000-1049, training seeds 1,000,000 and up);
``heldout`` scenarios never are. A suite's definition (every scenario's full config,
split and version, and the seed lists) is hashed like a leaderboard track
(:class:`leaderboard.tracks.Track`), so a result computed on another definition can be
told apart. Changing a scenario's dynamics makes a new version of it, and a new suite.

The score of a policy on a scenario is normalized by two per-scenario constants
(:func:`normalize`): 0 is the mean NSW of the ``random`` policy and 1 the mean proven
upper bound (:func:`wfbench.core.bound.score_upper_bound`) over the test seeds 0-49.
The constants are committed data in this package (``<suite>.json``), computed by
``benchmarks/suite_references.py`` which records the seeds and the wfbench version that
made them. ``tests/test_suite.py`` recomputes those of a cheap scenario. The aggregate over
scenarios (IQM, optimality gap, probability of improvement) is :mod:`wfbench.aggregate`.
``docs/suite.md`` has the rules and why each scenario is there.

The package is three small modules, each over the one before: ``definition`` (the
suites as data, :func:`get_suite`), ``score`` (the constants and :func:`normalize`) and
``run`` (:func:`evaluate_suite`, a policy over a suite's scenarios).
"""

from __future__ import annotations

from wfbench.suites.definition import SPLITS, SUITE_SCHEMA, SUITES, Suite, SuiteScenario, get_suite, suite_scenarios
from wfbench.suites.run import evaluate_suite
from wfbench.suites.score import DATA, REFERENCE_SEEDS, compute_reference, normalize, reference, references

__all__ = ["DATA", "REFERENCE_SEEDS", "SPLITS", "SUITES", "SUITE_SCHEMA", "Suite", "SuiteScenario",
           "compute_reference", "evaluate_suite", "get_suite", "normalize", "reference", "references",
           "suite_scenarios"]
