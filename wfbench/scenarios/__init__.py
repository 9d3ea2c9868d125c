"""Scenario suites: a versioned set of scenarios with a training and a held-out split, and the normalized score.

A suite is data (``suites``, :func:`get_suite`): each scenario a preset at a version
(``paper-64-v1``), its split and why it is there, hashed like a leaderboard track. ``score``
holds the committed constants and :func:`normalize` (0 the ``random`` policy, 1 the mean proven
bound over the test seeds); ``importer`` builds a scenario from real data; ``resolve`` is the one
reading of a scenario's name (:func:`resolve_scenario`, :func:`resolve_worlds`). The aggregate is
:mod:`wfbench.analysis.aggregate`; running a policy over a suite is the harness's
(``wfbench.evaluate_suite``). The rules and why each scenario is there: ``docs/suite.md``.
"""

from __future__ import annotations

from wfbench.scenarios.resolve import World, resolve_scenario, resolve_worlds
from wfbench.scenarios.score import DATA, REFERENCE_SEEDS, normalize, reference, references
from wfbench.scenarios.suites import SPLITS, SUITE_SCHEMA, SUITES, Suite, SuiteScenario, get_suite, suite_scenarios

__all__ = ["DATA", "REFERENCE_SEEDS", "SPLITS", "SUITES", "SUITE_SCHEMA", "Suite", "SuiteScenario", "World",
           "get_suite", "normalize", "reference", "references", "resolve_scenario", "resolve_worlds",
           "suite_scenarios"]
