"""A policy over a suite's scenarios: :func:`evaluate_suite`, one row per (scenario, seed) with its normalized score."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from wfbench.harness.evaluation import evaluate
from wfbench.scenarios.score import REFERENCE_SEEDS, normalize
from wfbench.scenarios.suites import Suite, SuiteScenario, get_suite

__all__ = ["compute_reference", "evaluate_suite"]


def evaluate_suite(policy: Any, suite: str | Suite = "suite-v1", seeds: int | str | Iterable[int] = "test",
                   split: str | None = None, scenarios: Sequence[str] | None = None, backend: str = "serial",
                   workers: int | None = None, address: str | None = None, progress: bool = False,
                   act_timeout_s: float | None = None, **kwargs: Any) -> Any:
    """Score ``policy`` on every scenario of a suite (or of one split): one row per (scenario, seed).

    Each scenario runs through :func:`wfbench.evaluate` (so every backend works unchanged);
    the rows gain ``scenario`` (the suite's id), ``split`` and ``normalized``
    (:func:`normalize`) before the evaluator's columns, which are kept as they come
    (the compute-budget columns included where the evaluator writes them).

    Args:
        policy: anything :func:`wfbench.evaluate` takes; loaded once for all scenarios.
        suite: a suite name or object.
        seeds: the seeds of every scenario (default ``"test"``, 0-49).
        split: ``"train"``, ``"heldout"`` or ``None`` for both.
        scenarios: a subset of the suite's ids (or unambiguous preset names); default all of the split.
        backend: ``serial``, ``process`` or ``ray``, as for :func:`wfbench.evaluate`.
        workers: processes or Ray tasks.
        address: Ray cluster address.
        progress: show a progress bar per scenario.
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy (default: the evaluator's;
            0 for none).
        **kwargs: passed on to :func:`wfbench.evaluate` (``threads``).

    Returns:
        The DataFrame; ``attrs`` holds ``suite``, ``suite_hash``, ``policy``, ``split`` and, where the
        evaluator reports one, ``budget`` per scenario id.

    Raises:
        ValueError: an unknown suite, split or scenario, or a bad seed list or backend.
    """
    import pandas as pd

    from wfbench.harness.evaluation import evaluate
    from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, load_policy

    s = get_suite(suite)
    ids = s.ids(split)  # an unknown split fails here
    chosen = [s.scenario(i) for i in ids] if scenarios is None else [s.scenario(x) for x in scenarios]
    chosen = [c for c in chosen if split is None or c.split == split]
    loaded = load_policy(policy, DEFAULT_ACT_TIMEOUT_S if act_timeout_s is None else act_timeout_s)
    frames, budgets = [], {}
    for sc in chosen:
        df = evaluate(loaded, sc.config, seeds, backend=backend, workers=workers, address=address,
                      progress=progress, **kwargs)
        if "budget" in df.attrs:
            budgets[sc.id] = df.attrs["budget"]
        df.insert(0, "normalized", normalize(df["nsw"].to_numpy(), sc.id, s))
        df.insert(0, "split", sc.split)
        df.insert(0, "scenario", sc.id)
        frames.append(df)
    out = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    out.attrs.update(suite=s.name, suite_hash=s.hash, policy=loaded.name, split=split)
    if budgets:
        out.attrs["budget"] = budgets
    return out


def compute_reference(scenario: SuiteScenario, seeds: Iterable[int] = REFERENCE_SEEDS,
                      backend: str = "serial", workers: int | None = None) -> dict[str, Any]:
    """The normalization constants of one scenario, as the reference file stores them.

    ``random_ref`` is the mean NSW of the ``random`` policy and ``bound_ref`` the mean
    proven upper bound over ``seeds``; ``hash`` is the scenario's, so a later change of
    its definition is caught. ``tools/suite_references.py`` writes these.
    """
    from wfbench.core.bound import score_upper_bound

    seeds = list(seeds)
    random_ref = float(evaluate("random", scenario.config, seeds, backend=backend, workers=workers)["nsw"].mean())
    bound_ref = float(np.mean(score_upper_bound(scenario.config, seeds)))
    return {"random_ref": random_ref, "bound_ref": bound_ref, "hash": scenario.hash}
