"""Scenario suites: a versioned set of scenarios with a training and a held-out split, and the normalized score.

A suite is data: each scenario is a preset plus a version (its id is ``<preset>-v<version>``,
e.g. ``paper-64-v1``), the split it belongs to and why it is there. ``train`` scenarios
may be tuned and trained on (public seeds 1000-1049, training seeds 1,000,000 and up);
``heldout`` scenarios never are. A suite's definition (every scenario's full config,
split and version, and the seed lists) is hashed like a leaderboard track
(:class:`wfbench.leaderboard.tracks.Track`), so a result computed on another definition can be
told apart. Changing a scenario's dynamics makes a new version of it, and a new suite.

The score of a policy on a scenario is normalized by two per-scenario constants
(:func:`normalize`): 0 is the mean NSW of the ``random`` policy and 1 the mean proven
upper bound (:func:`wfbench.core.bound.score_upper_bound`) over the test seeds 0-49.
The constants are committed data in this package (``<suite>.json``), computed by
``tools/suite_references.py`` which records the seeds and the wfbench version that
made them. ``tests/scenarios/test_suite.py`` recomputes those of a cheap scenario. The aggregate over
scenarios (IQM, optimality gap, probability of improvement) is :mod:`wfbench.analysis.aggregate`.
``docs/suite.md`` has the rules and why each scenario is there.

The package says where worlds come from: ``suites`` (the suites as data,
:func:`get_suite`), ``score`` (the constants and :func:`normalize`), ``importer``
(a scenario built from real data) and ``resolve``, the one reading of a scenario's name
(:func:`resolve_scenario`: a preset, a suite's id such as ``paper-64-v1`` or a file;
:func:`resolve_worlds`: several, with suite ids and ``suite-v1:train``). Running a policy over a suite is the harness's
(:func:`wfbench.harness.suite.evaluate_suite`, also ``wfbench.evaluate_suite``).
"""

from __future__ import annotations

from wfbench.scenarios.resolve import World, resolve_scenario, resolve_worlds
from wfbench.scenarios.score import DATA, REFERENCE_SEEDS, normalize, reference, references
from wfbench.scenarios.suites import SPLITS, SUITE_SCHEMA, SUITES, Suite, SuiteScenario, get_suite, suite_scenarios

__all__ = ["DATA", "REFERENCE_SEEDS", "SPLITS", "SUITES", "SUITE_SCHEMA", "Suite", "SuiteScenario", "World",
           "get_suite", "normalize", "reference", "references", "resolve_scenario", "resolve_worlds",
           "suite_scenarios"]
