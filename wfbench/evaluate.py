"""Evaluate a policy on a scenario over seeds: a DataFrame with one row per seed.

All seeds of one call run as one batch (one compiled rollout for built-in composites,
one batched ``act``/``step`` loop otherwise). Results do not depend on the backend, on
how seeds are split into batches, or on the number of threads: each environment is
independent and all randomness is indexed by the seed.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from wfbench.backends import BACKENDS  # noqa: F401 - re-exported for the CLI
from wfbench.config import ScenarioConfig
from wfbench.simulator import Simulator
from wfbench.state import COUNTERS, INVALID_COUNTERS, METRICS

KPIS = ("workforce_cost", "utilization", "downtime", "nsw")
KPI_LABELS = {
    "workforce_cost": "Workforce cost",
    "utilization": "Personnel util. rate",
    "downtime": "Facility downtime",
    "nsw": "Nash social welfare",
}


def resolve_seeds(seeds: int | Iterable[int]) -> list[int]:
    """``n`` means seeds ``0..n-1``; otherwise a sequence of distinct integers >= 0."""
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ValueError(f"seeds = {seeds}: allowed: a count >= 1 or a list of integers >= 0")
        return list(range(int(seeds)))
    out = [int(s) for s in seeds]
    if not out:
        raise ValueError("seeds is empty; allowed: a count >= 1 or a list of integers >= 0")
    if any(s < 0 for s in out):
        raise ValueError(f"seeds must be >= 0, got {min(out)}")
    if len(set(out)) != len(out):
        raise ValueError("seeds must be distinct")
    return out


@dataclass
class BatchResult:
    seeds: list[int]
    means: dict[str, np.ndarray]
    counters: dict[str, np.ndarray]
    steps: np.ndarray
    series: np.ndarray | None  # (B, horizon, len(METRICS)) float32


def run_batch(policy: Any, config: ScenarioConfig, seeds: Sequence[int], keep_series: bool = False,
              threads: int | None = None) -> BatchResult:
    """Run full episodes of ``seeds`` as one batch."""
    from policies import get
    from policies import Composite
    from policies.rollout import rollout

    policy = get(policy)
    sim = Simulator(config, seeds, keep_series=keep_series)
    if isinstance(policy, Composite) and policy.compiled:
        codes, hp, pstate = policy.compiled_plan(seeds, sim.M, sim.N)
        rollout(sim, codes, hp, pstate, threads)
    else:
        obs = sim.reset()
        policy.reset(sim.seeds)
        while not sim.done:
            sim.step(policy.act(obs))
            obs = sim.observe()
    return BatchResult(
        seeds=list(seeds), means=sim.episode_means(), counters=sim.counters(), steps=sim.state.t.copy(),
        series=sim.state.series.copy() if keep_series else None,
    )


def _frame(results: list[BatchResult], config: ScenarioConfig, policy_name: str) -> pd.DataFrame:
    rows = []
    for r in results:
        for i, seed in enumerate(r.seeds):
            row: dict[str, Any] = {"seed": seed}
            for k in METRICS:
                row[k] = float(r.means[k][i])
            row["episode_length"] = int(r.steps[i])
            for c in COUNTERS:
                row[c] = int(r.counters[c][i])
            row["invalid_actions"] = int(sum(r.counters[c][i] for c in INVALID_COUNTERS))
            rows.append(row)
    df = pd.DataFrame(rows)
    df.attrs["scenario"] = config.name
    df.attrs["policy"] = policy_name
    return df


def evaluate(policy: Any, scenario: str | ScenarioConfig, seeds: int | Iterable[int] = 50, backend: str = "serial",
             workers: int | None = None, threads: int | None = None, progress: bool = False,
             return_series: bool = False, address: str | None = None) -> pd.DataFrame | tuple[pd.DataFrame, np.ndarray]:
    """Score ``policy`` on ``scenario`` over ``seeds``; one row per seed, in seed order.

    Args:
        policy: a registry name (``policies.names()``), a ``module:attr`` entry point or
            a policy object.
        scenario: a preset name, a .toml/.json path or a :class:`ScenarioConfig`.
        seeds: a count ``n`` (seeds ``0..n-1``) or a sequence of seeds.
        backend: ``"serial"`` (this process; built-in composites use ``threads``
            numba threads, all cores by default), ``"process"`` (a pool of ``workers``
            processes over chunks of seeds) or ``"ray"`` (Ray tasks; ``address`` joins
            an existing cluster). See :mod:`wfbench.backends`; the numbers do not
            depend on the backend.
        workers: processes or Ray tasks for the parallel backends (default: all cores).
        threads: numba threads for the ``serial`` backend.
        progress: show a progress bar.
        return_series: also return the per-step metrics, (seeds, horizon, metrics).
        address: Ray cluster address for ``backend="ray"``.

    Returns:
        The DataFrame (columns ``seed``, the KPIs, utilities, ``episode_length`` and the
        action counters), and with ``return_series`` the series array whose last axis
        follows ``wfbench.state.METRICS``.
    """
    from policies import get
    from wfbench.backends import check_backend, run_chunks

    config = ScenarioConfig.resolve(scenario)
    seed_list = resolve_seeds(seeds)
    check_backend(backend, address)
    policy_obj = get(policy)
    policy_name = policy if isinstance(policy, str) else getattr(policy_obj, "name", type(policy_obj).__name__)
    spec = policy if isinstance(policy, str) else policy_obj
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(seed_list), desc=f"{policy_name} on {config.name}", unit="episode", leave=False)
    results: list[BatchResult] = []
    try:
        run_spec = policy_obj if backend == "serial" else spec
        for r in run_chunks(run_spec, config, seed_list, backend=backend, workers=workers, address=address,
                            keep_series=return_series, threads=threads):
            results.append(r)
            if bar:
                bar.update(len(r.seeds))
    finally:
        if bar:
            bar.close()
    df = _frame(results, config, policy_name)
    order = {s: i for i, s in enumerate(seed_list)}
    rank = df["seed"].map(order).to_numpy()
    df = df.iloc[np.argsort(rank, kind="stable")].reset_index(drop=True)
    df.attrs.update(scenario=config.name, policy=policy_name)
    if return_series:
        series = np.concatenate([r.series for r in results if r.series is not None], axis=0)
        return df, series[np.argsort(rank, kind="stable")]
    return df


def summarize(df: pd.DataFrame, columns: Sequence[str] = KPIS) -> dict[str, tuple[float, float, float]]:
    """Mean, 25% and 75% quantile of each column over the seeds."""
    return {c: (float(df[c].mean()), float(df[c].quantile(0.25)), float(df[c].quantile(0.75))) for c in columns}


def format_kpi(mean: float, q25: float, q75: float, digits: int = 3) -> str:
    return f"{mean:.{digits}g} ({q25:.{digits}g}-{q75:.{digits}g})"
