"""The normalized score of a suite scenario and its published constants.

``normalize(nsw, scenario_id)`` = ``(nsw - random_ref) / (bound_ref - random_ref)``: 0 is
the mean NSW of the ``random`` policy, 1 the mean proven upper bound, over the test
seeds 0-49. The constants are committed beside this module (``<suite>.json``), written by
``tools/suite_references.py`` with :func:`wfbench.harness.suite.compute_reference`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from wfbench.core.seeds import TEST
from wfbench.scenarios.suites import SUITES, Suite, lookup

REFERENCE_SEEDS = tuple(TEST)  # the seeds of the normalization constants: the test seeds 0-49
DATA = Path(__file__).parent

__all__ = ["DATA", "REFERENCE_SEEDS", "normalize", "reference", "references", "scale"]


@cache
def _reference_file(name: str) -> dict[str, Any]:
    path = DATA / f"{name}.json"
    if not path.exists():
        raise ValueError(f"suite {name!r} has no reference constants ({path.name}); "
                         "compute them with tools/suite_references.py")
    return json.loads(path.read_text())


def references(suite: str | Suite = "suite-v1") -> dict[str, Any]:
    """The suite's published normalization constants, as committed.

    The seeds and wfbench version that made them, and per scenario id ``random_ref``,
    ``bound_ref`` and the scenario ``hash`` they were computed for.
    """
    name = suite.name if isinstance(suite, Suite) else suite
    if name not in SUITES:
        raise ValueError(f"unknown suite {name!r}; allowed: {', '.join(SUITES)}")
    return _reference_file(name)


def reference(scenario_id: str, suite: str | Suite = "suite-v1") -> tuple[float, float]:
    """``(random_ref, bound_ref)`` of one scenario; fails if its definition changed since they were computed."""
    name, sc = lookup(suite, scenario_id)
    entry = _reference_file(name)["scenarios"].get(sc.id)
    if entry is None:
        raise ValueError(f"{name}: no reference constants for {sc.id} yet; compute them with "
                         f"tools/suite_references.py --scenarios {sc.id}")
    if entry["hash"] != sc.hash:
        raise ValueError(f"{name}: the reference constants of {sc.id} were computed for another definition "
                         f"(hash {entry['hash']}, now {sc.hash}); recompute them with tools/suite_references.py")
    return float(entry["random_ref"]), float(entry["bound_ref"])


def normalize(nsw: float | np.ndarray | Sequence[float], scenario_id: str,
              suite: str | Suite = "suite-v1") -> float | np.ndarray:
    """The normalized score ``(nsw - random_ref) / (bound_ref - random_ref)`` of a scenario.

    0 is the mean score of the ``random`` policy, 1 the mean proven upper bound over the
    test seeds; a policy can score below 0, and above 1 only on a seed whose own bound is
    above the mean.

    Args:
        nsw: an episode-mean NSW or an array of them.
        scenario_id: the suite's id (``paper-64-v1``) or, where unambiguous, the preset name.
        suite: the suite (name or object) whose constants to use.

    Returns:
        A float for a scalar, an array otherwise.
    """
    out = scale(nsw, *reference(scenario_id, suite))
    return float(out) if out.ndim == 0 else out


def scale(nsw: float | np.ndarray | Sequence[float], random_ref: float, bound_ref: float) -> np.ndarray:
    """``(nsw - random_ref) / (bound_ref - random_ref)``: the normalized score with given constants (an array)."""
    return (np.asarray(nsw, dtype=float) - random_ref) / (bound_ref - random_ref)


