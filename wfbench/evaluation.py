"""Evaluate a policy on a scenario over seeds: a DataFrame with one row per seed.

All seeds of one call run as one batch (one compiled rollout for built-in composites,
one batched ``act``/``step`` loop otherwise), or as one batch per worker on the
parallel backends (:mod:`wfbench.backends`). Results do not depend on the backend, on
how seeds are split into batches, or on the number of threads: each environment is
independent and all randomness is indexed by the seed. A user's policy runs through
its guard (:mod:`wfbench.guard`): its failures name its file and line, and each call
has a time limit.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from policies.registry import warn_if_trained_elsewhere
from wfbench.backends import BACKENDS, check_backend, run_chunks
from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
from wfbench.core.seeds import resolve_seeds
from wfbench.guard import DEFAULT_ACT_TIMEOUT_S, load_policy
from wfbench.runner import BatchResult, results_frame

__all__ = ["BACKENDS", "KPIS", "KPI_LABELS", "evaluate", "format_kpi", "resolve_seeds", "summarize"]

KPIS = KPI_NAMES  # the KPI table's names (wfbench.core.kpis), the columns every summary shows


def evaluate(policy: Any, scenario: str | ScenarioConfig, seeds: int | str | Iterable[int] = 50,
             backend: str = "serial",
             workers: int | None = None, threads: int | None = None, progress: bool = False,
             return_series: bool = False, address: str | None = None,
             act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S) -> pd.DataFrame | tuple[pd.DataFrame, np.ndarray]:
    """Score ``policy`` on ``scenario`` over ``seeds``; one row per seed, in seed order.

    Args:
        policy: a registry name (``policies.names()``), a ``module:attr`` entry point, a
            policy object (its class may live in ``__main__`` or a notebook cell) or a
            :class:`wfbench.guard.LoadedPolicy`. Resolved once per call.
        scenario: a preset name, a .toml/.json path or a :class:`ScenarioConfig`.
        seeds: a count ``n`` (seeds ``0..n-1``), a named set (``"test"``, ``"public"``, ``"train:N"``;
            :mod:`wfbench.core.seeds`) or a sequence of seeds.
        backend: ``"serial"`` (this process; built-in composites use ``threads``
            numba threads, all cores by default), ``"process"`` (a pool of ``workers``
            processes over chunks of seeds; works from a script without a
            ``__main__`` guard and from a notebook) or ``"ray"`` (Ray tasks;
            ``address`` joins an existing cluster). See :mod:`wfbench.backends`; the
            numbers do not depend on the backend.
        workers: processes or Ray tasks for the parallel backends (default: all cores).
        threads: numba threads for the ``serial`` backend.
        progress: show a progress bar.
        return_series: also return the per-step metrics, (seeds, horizon, metrics).
        address: Ray cluster address for ``backend="ray"``.
        act_timeout_s: time limit in seconds of each ``reset`` and ``act`` call of a
            policy that is not a built-in registry name; ``None`` or 0 for no limit.

    Returns:
        The DataFrame (columns ``seed``, the KPIs, utilities, ``episode_length`` and the
        action counters), and with ``return_series`` the series array whose last axis
        follows ``wfbench.core.state.METRICS``.

    Raises:
        ValueError: a bad scenario, seed list, backend or limit;
            :class:`wfbench.guard.PolicyLoadError` (a ValueError) for a spec that names
            no policy.
        wfbench.guard.PolicyError: the policy raised, hung past ``act_timeout_s`` or
            returned a malformed action; its message names the policy, file and line.
    """
    config = ScenarioConfig.resolve(scenario)
    seed_list = resolve_seeds(seeds)
    check_backend(backend, address)
    loaded = load_policy(policy, act_timeout_s)
    warn_if_trained_elsewhere(loaded.policy, config.name)  # once, here: a worker's warning would repeat or be lost
    bar = None
    if progress:
        bar = tqdm(total=len(seed_list), desc=f"{loaded.name} on {config.name}", unit="episode", leave=False)
    results: list[BatchResult] = []
    try:
        for r in run_chunks(loaded, config, seed_list, backend=backend, workers=workers, address=address,
                            keep_series=return_series, threads=threads):
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
    df.attrs.update(scenario=config.name, policy=loaded.name)
    if return_series:
        series = np.concatenate([r.series for r in results if r.series is not None], axis=0)
        return df, series[rank]
    return df


def summarize(df: pd.DataFrame, columns: Sequence[str] = KPIS) -> dict[str, tuple[float, float, float]]:
    """Mean, 25% and 75% quantile of each column over the seeds."""
    return {c: (float(df[c].mean()), float(df[c].quantile(0.25)), float(df[c].quantile(0.75))) for c in columns}


def format_kpi(mean: float, q25: float, q75: float, digits: int = 3) -> str:
    return f"{mean:.{digits}g} ({q25:.{digits}g}-{q75:.{digits}g})"
