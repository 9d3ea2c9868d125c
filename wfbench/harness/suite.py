"""A policy over a suite's scenarios: :func:`evaluate_suite`, one row per (scenario, seed) with its normalized score."""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from wfbench.harness.backends import SERIAL, Execution, check_execution
from wfbench.harness.evaluation import evaluate
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, load_policy
from wfbench.policies.registry import ScenarioMismatchWarning
from wfbench.scenarios.score import REFERENCE_SEEDS, normalize
from wfbench.scenarios.suites import Suite, SuiteScenario, get_suite

__all__ = ["compute_reference", "evaluate_suite", "suite_cells", "suite_summary"]


def evaluate_suite(policy: Any, suite: str | Suite = "suite-v1", seeds: int | str | Iterable[int] = "test",
                   split: str | None = None, scenarios: Sequence[str] | None = None, *,
                   act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S,
                   execution: Execution | None = None) -> Any:
    """Score ``policy`` on every scenario of a suite (or of one split): one row per (scenario, seed).

    Each scenario runs through :func:`wfbench.evaluate` (so every backend works unchanged),
    with no :class:`~wfbench.policies.registry.ScenarioMismatchWarning` on the held-out split;
    the rows gain ``scenario`` (the suite's id), ``split`` and ``normalized``
    (:func:`normalize`) before the evaluator's columns, which are kept as they come
    (the compute-budget columns included where the evaluator writes them).

    Args:
        policy: anything :func:`wfbench.evaluate` takes; loaded once for all scenarios.
        suite: a suite name or object.
        seeds: the seeds of every scenario (default ``"test"``, 0-49).
        split: ``"train"``, ``"heldout"`` or ``None`` for both.
        scenarios: a subset of the suite's ids (or unambiguous preset names); default all of the split.
        act_timeout_s: limit in seconds of each ``reset``/``act`` call of a policy that is not a
            built-in registry name, as for :func:`wfbench.evaluate`: default
            :data:`wfbench.harness.guard.DEFAULT_ACT_TIMEOUT_S`, ``None`` or 0 for no limit.
        execution: where and how the episodes play, one
            :class:`~wfbench.harness.backends.Execution` handed to every scenario's evaluation
            (as for :func:`wfbench.evaluate`); ``None``: serial, in this process.

    Returns:
        The DataFrame; ``attrs`` holds ``suite``, ``suite_hash``, ``policy``, ``split`` and, where the
        evaluator reports one, ``budget`` per scenario id.

    Raises:
        ValueError: an unknown suite, split or scenario, or a bad seed list.
    """
    import pandas as pd

    run = check_execution(execution, SERIAL)
    s = get_suite(suite)
    ids = s.ids(split)  # an unknown split fails here
    chosen = [s.scenario(i) for i in ids] if scenarios is None else [s.scenario(x) for x in scenarios]
    chosen = [c for c in chosen if split is None or c.split == split]
    loaded = load_policy(policy, act_timeout_s)
    frames, budgets = [], {}
    for sc in chosen:
        with warnings.catch_warnings():  # zero-shot is the point of the held-out split: no mismatch warning there
            if sc.split == "heldout":
                warnings.simplefilter("ignore", ScenarioMismatchWarning)
            df = evaluate(loaded, sc.config, seeds, execution=run)
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


def suite_cells(df: Any) -> tuple[list[str], list[list[str]]]:
    """Header and text cells of an :func:`evaluate_suite` frame: a row per scenario, means over seeds.

    The columns are the scenario, its split, each KPI, the normalized score and the
    compute-budget columns the frame has (:data:`wfbench.harness.budget.BUDGET_COLUMNS`).
    """
    from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
    from wfbench.harness.budget import BUDGET_COLUMNS

    budget = [c for c in BUDGET_COLUMNS if c in df.columns]
    header = ["Scenario", "Split", *[KPI_LABELS[k] for k in KPI_NAMES], "Normalized", *budget]
    rows = []
    for sc, g in df.groupby("scenario", sort=False):
        rows.append([sc, g["split"].iloc[0], *[f"{g[k].mean():.4g}" for k in KPI_NAMES],
                     f"{g['normalized'].mean():.3f}", *[f"{g[c].mean():.3g}" for c in budget]])
    return header, rows


def suite_summary(df: Any, seeds: Sequence[int], aggregates: dict[str, Any] | None = None,
                  policy: str | None = None) -> dict[str, Any]:
    """An :func:`evaluate_suite` frame as a JSON-ready dict, as ``wfbench evaluate --suite --format json`` prints it.

    Args:
        df: the frame (its ``attrs`` name the policy, suite, hash and split).
        seeds: the seeds it ran.
        aggregates: :func:`wfbench.analysis.aggregate.aggregate_suite` of it (default: computed here).
        policy: the policy's name as given (default the frame's, the loaded policy's name).

    Returns:
        ``policy``, ``suite``, ``suite_hash``, ``split``, ``seeds``, per scenario its split,
        mean normalized score and mean KPIs, and per split the aggregate's row.
    """
    from wfbench.analysis.aggregate import aggregate_suite
    from wfbench.core.kpis import KPI_NAMES

    policy = df.attrs["policy"] if policy is None else policy
    aggs = aggregate_suite({policy: df}) if aggregates is None else aggregates
    return {"policy": policy, "suite": df.attrs["suite"], "suite_hash": df.attrs["suite_hash"],
            "split": df.attrs["split"], "seeds": list(seeds),
            "scenarios": {sc: {"split": g["split"].iloc[0], "normalized": float(g["normalized"].mean()),
                               **{k: float(g[k].mean()) for k in KPI_NAMES}}
                          for sc, g in df.groupby("scenario", sort=False)},
            "aggregate": {split: a.table.drop(columns="policy").iloc[0].to_dict() for split, a in aggs.items()}}


def compute_reference(scenario: SuiteScenario, seeds: Iterable[int] = REFERENCE_SEEDS,
                      execution: Execution | None = None) -> dict[str, Any]:
    """The normalization constants of one scenario, as the reference file stores them.

    ``random_ref`` is the mean NSW of the ``random`` policy and ``bound_ref`` the mean
    proven upper bound over ``seeds``; ``hash`` is the scenario's, so a later change of
    its definition is caught. ``execution`` says where the ``random`` runs play
    (default: serial, in this process); it changes no number. ``tools/suite_references.py``
    writes these.
    """
    from wfbench.core.bound import score_upper_bound

    seeds = list(seeds)
    random_ref = float(evaluate("random", scenario.config, seeds, execution=execution)["nsw"].mean())
    bound_ref = float(np.mean(score_upper_bound(scenario.config, seeds)))
    return {"random_ref": random_ref, "bound_ref": bound_ref, "hash": scenario.hash}
