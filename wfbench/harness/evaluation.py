"""Evaluate a policy on a scenario over seeds: a DataFrame with one row per seed.

:func:`evaluate` (``wfbench.evaluate``) checks the scenario and seeds and runs the seeds as
batches on a backend (:mod:`wfbench.harness.backends`); no number depends on the backend, the
batching or the threads. A user's policy runs through its guard (:mod:`wfbench.harness.guard`).
Each row also carries the budget columns (:mod:`wfbench.harness.budget`), and
``df.attrs["budget"]`` says where and how it ran; compare results with
:func:`wfbench.harness.budget.results_only`. ``docs/design.md``, "One Execution value", and
``docs/leaderboard.md``, "What a result cost".
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
from wfbench.core.seeds import resolve_seeds
from wfbench.harness.backends import BACKENDS, SERIAL, Execution, check_execution, run_chunks
from wfbench.harness.budget import BUDGET_COLUMNS, policy_budget, results_only
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, LoadedPolicy, load_policy
from wfbench.harness.runner import BatchResult, results_frame
from wfbench.policies.registry import warn_if_trained_elsewhere
from wfbench.scenarios.resolve import resolve_scenario

__all__ = ["BACKENDS", "BUDGET_COLUMNS", "KPI_LABELS", "KPI_NAMES", "Execution", "evaluate", "format_kpi",
           "resolve_seeds", "results_only", "summarize"]

def evaluate(policy: Any, scenario: str | ScenarioConfig, seeds: int | str | Iterable[int] = 50, *,
             return_series: bool = False, act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S,
             execution: Execution | None = None) -> pd.DataFrame | tuple[pd.DataFrame, np.ndarray]:
    """Score ``policy`` on ``scenario`` over ``seeds``; one row per seed, in seed order.

    Args:
        policy: a registry name (``policies.names()``), a ``module:attr`` entry point, a
            policy object (its class may live in ``__main__`` or a notebook cell) or a
            :class:`wfbench.harness.guard.LoadedPolicy`. Resolved once per call.
        scenario: a scenario name (a preset, a suite's scenario id such as ``paper-64-v1`` or a
            .toml/.json path; :func:`wfbench.scenarios.resolve.resolve_scenario`), resolved once
            here, or a :class:`ScenarioConfig`.
        seeds: a count ``n`` (seeds ``0..n-1``), a named set (``"test"``, ``"public"``, ``"train:N"``;
            :mod:`wfbench.core.seeds`) or a sequence of seeds.
        return_series: also return the per-step metrics, (seeds, horizon, metrics).
        act_timeout_s: time limit in seconds of each ``reset`` and ``act`` call of a
            policy that is not a built-in registry name; ``None`` or 0 for no limit.
        execution: where and how the episodes play, as one
            :class:`~wfbench.harness.backends.Execution`: its ``backend`` is ``"serial"``
            (this process; built-in composites use ``threads`` numba threads, all cores by
            default), ``"process"`` (a pool of ``workers`` processes over chunks of seeds;
            works from a script without a ``__main__`` guard and from a notebook) or
            ``"ray"`` (Ray tasks; ``address`` joins an existing cluster), and it carries
            ``chunk_size`` and ``progress``. ``None``: serial, in this process. The numbers
            do not depend on it (:mod:`wfbench.harness.backends`).

    Returns:
        The DataFrame (columns ``seed``, the KPIs, utilities, ``episode_length``, the
        action counters and the budget columns; ``attrs["budget"]``, :func:`budget_record`),
        and with ``return_series`` the series array whose last axis follows
        ``wfbench.core.state.METRICS``.

    Raises:
        ValueError: a bad scenario, seed list or limit, or an ``execution`` that is not an
            :class:`~wfbench.harness.backends.Execution`;
            :class:`wfbench.harness.guard.PolicyLoadError` (a ValueError) for a spec that names
            no policy.
        wfbench.harness.guard.PolicyError: the policy raised, hung past ``act_timeout_s`` or
            returned a malformed action; its message names the policy, file and line.
    """
    run = check_execution(execution, SERIAL)
    config = resolve_scenario(scenario)
    seed_list = resolve_seeds(seeds)
    loaded = load_policy(policy, act_timeout_s)
    warn_if_trained_elsewhere(loaded.policy, config.name)  # once, here: a worker's warning would repeat or be lost
    bar = None
    if run.progress:
        bar = tqdm(total=len(seed_list), desc=f"{loaded.name} on {config.name}", unit="episode", leave=False)
    results: list[BatchResult] = []
    try:
        for r in run_chunks(loaded, config, seed_list, run, keep_series=return_series):
            results.append(r)
            if bar:
                bar.update(len(r.seeds))
    finally:
        if bar:
            bar.close()
    df = results_frame(results, config, loaded.name)
    order = {s: i for i, s in enumerate(seed_list)}
    rank = np.argsort(df["seed"].map(order).to_numpy(), kind="stable")
    df = df.iloc[rank].reset_index(drop=True)
    df.attrs.update(scenario=config.name, policy=loaded.name,
                    budget=budget_record(results, loaded, policy, run),
                    batches=[[int(s) for s in r.seeds] for r in results])  # a network's totals depend on its batch
    if return_series:
        series = np.concatenate([r.series for r in results if r.series is not None], axis=0)
        return df, series[rank]
    return df


def budget_record(results: Sequence[BatchResult], loaded: LoadedPolicy, spec: Any,
                  execution: Execution) -> dict[str, Any]:
    """What ``df.attrs["budget"]`` holds: where the chunks ran and what the policy states about its cost.

    Keys: ``machine`` (:func:`wfbench.harness.budget.machine` of the process that ran the chunks;
    ``machines`` instead when they ran on several, as on a Ray cluster), ``backend``,
    ``workers`` (processes or tasks; ``threads`` for serial), ``timing`` (``"act"``: each
    act call timed; ``"rollout"``: a compiled rollout's CPU time per environment-step),
    ``chunks`` and ``policy`` (:func:`wfbench.harness.budget.policy_budget`).
    """
    machines = list({json.dumps(r.machine, sort_keys=True): r.machine for r in results}.values())
    parallel = execution.backend != "serial" and len(results) > 1
    out: dict[str, Any] = {
        "backend": execution.backend,
        "workers": (execution.workers or os.cpu_count() or 1) if parallel else 1,
        "threads": 1 if parallel else execution.threads,
        "timing": results[0].timing if results else "",
        "chunks": len(results),
        "policy": policy_budget(_spec(loaded, spec), loaded.policy),
    }
    if len(machines) == 1:
        out["machine"] = machines[0]
    else:
        out["machines"] = machines
    return out


def _spec(loaded: LoadedPolicy, spec: Any) -> str | None:
    """The registry name, file or entry point the policy was given by, or None for an object."""
    if isinstance(spec, str):
        return spec
    if isinstance(spec, LoadedPolicy) and spec.guard is None:  # loaded from a registry name
        return spec.name
    return None


def summarize(df: pd.DataFrame, columns: Sequence[str] = KPI_NAMES) -> dict[str, tuple[float, float, float]]:
    """Mean, 25% and 75% quantile of each column over the seeds."""
    return {c: (float(df[c].mean()), float(df[c].quantile(0.25)), float(df[c].quantile(0.75))) for c in columns}


def format_kpi(mean: float, q25: float, q75: float, digits: int = 3) -> str:
    return f"{mean:.{digits}g} ({q25:.{digits}g}-{q75:.{digits}g})"
