"""Several policies on the same seeds: KPIs, NSW intervals and paired differences to a baseline.

:func:`compare` does it on one scenario; :func:`compare_suite` over a suite's scenarios,
paired per scenario and aggregated per split (:mod:`wfbench.analysis.aggregate`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from wfbench.analysis.plots import comparison_figure, figure_format, save_figure
from wfbench.analysis.stats import bootstrap_ci, paired_difference
from wfbench.analysis.tables import markdown_table, text_table
from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
from wfbench.harness.backends import SERIAL, Execution, check_execution
from wfbench.harness.evaluation import evaluate, format_kpi, resolve_seeds, summarize
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, load_policy
from wfbench.scenarios.resolve import resolve_scenario

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


def compare(policies: Sequence[Any], scenario: str | ScenarioConfig, seeds: int | str | Iterable[int] = 50,
            baseline: str = "heuristic", *, act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S,
            plot: str | Path | None = None, execution: Execution | None = None) -> pd.DataFrame:
    """One row per policy (baseline included): KPI summaries, NSW 95% interval, paired NSW difference.

    Every policy runs on the same seeds, so the difference to the baseline is paired by
    seed (:func:`wfbench.analysis.stats.paired_difference`). Every policy is loaded before the
    first one runs, so a bad name fails at once. Rows keep the order given, the
    baseline first if it was not listed; ``df.attrs["baseline_added"]`` says whether it
    was added. ``df.attrs["runs"]`` holds the per-seed frames.

    Args:
        policies: registry names, ``module:attr`` entry points or policy objects.
        scenario: a scenario name (:func:`wfbench.scenarios.resolve.resolve_scenario`) or a
            :class:`ScenarioConfig`, resolved once here.
        seeds: a count ``n`` (seeds ``0..n-1``), a named set (``"test"``, ``"public"``, ``"train:N"``;
            :mod:`wfbench.core.seeds`) or a sequence of seeds.
        baseline: the policy the differences are taken to (a name or entry point).
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy.
        plot: also write the comparison's figure here (:func:`plot_comparison`); the suffix
            picks the format (``.png``, ``.svg`` or ``.pdf``); the path is checked before anything
            runs (:func:`check_plot_path`).
        execution: where and how the episodes play, one
            :class:`~wfbench.harness.backends.Execution` handed to every policy's evaluation
            (:func:`wfbench.harness.evaluation.evaluate`); ``None``: serial, in this process.

    Returns:
        The comparison, one row per policy.

    Raises:
        ValueError: a bad scenario, seed list or plot path; :class:`wfbench.harness.guard.PolicyLoadError`
            (a ValueError) for a spec that names no policy.
    """
    run = check_execution(execution, SERIAL)
    if plot is not None:
        check_plot_path(plot)  # a bad suffix or folder fails before the runs, not after them
    config = resolve_scenario(scenario)
    seed_list = resolve_seeds(seeds)
    added = baseline not in policies
    loaded = [load_policy(p, act_timeout_s) for p in ([baseline, *policies] if added else policies)]
    by_name = {lp.name: lp for lp in loaded}  # a policy listed twice runs once
    runs = {name: evaluate(lp, config, seed_list, execution=run) for name, lp in by_name.items()}
    base = runs[baseline]["nsw"].to_numpy()
    rows = []
    for name, df in runs.items():
        row: dict[str, Any] = {"policy": name}
        for k, (mean, q25, q75) in summarize(df).items():
            row[k], row[f"{k}_q25"], row[f"{k}_q75"] = mean, q25, q75
        ci = bootstrap_ci(df["nsw"].to_numpy())
        row["nsw_ci_low"], row["nsw_ci_high"] = ci.low, ci.high
        d = paired_difference(df["nsw"].to_numpy(), base)
        row["nsw_diff"], row["nsw_diff_low"], row["nsw_diff_high"] = d
        row["wins"] = int((df["nsw"].to_numpy() > base).sum())
        rows.append(row)
    out = pd.DataFrame(rows)
    out.attrs.update(scenario=config.name, seeds=seed_list, baseline=baseline, baseline_added=added, runs=runs)
    if plot is not None:
        plot_comparison(out, plot)
    return out


def check_plot_path(path: str | Path, what: str = "plot") -> Path:
    """``path`` as a Path if a figure can be written there, else ValueError saying why.

    The suffix must name a format (``.png``, ``.svg`` or ``.pdf``), the folder must exist
    and the path must not be a folder. :func:`compare` and :func:`plot_comparison` check
    this before they draw, ``wfbench compare --plot`` before anything runs.

    Args:
        path: where the figure goes.
        what: how the messages name the path (``"--plot"`` on the command line).

    Returns:
        The path.
    """
    try:
        figure_format(path)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    out = Path(path)
    if not out.parent.is_dir():
        raise ValueError(f"{what} {str(path)!r}: folder {str(out.parent)!r} does not exist")
    if out.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a folder; give a file name")
    return out


def plot_comparison(df: pd.DataFrame, path: str | Path | None = None) -> Figure:
    """The figure of a comparison: KPI distributions per policy and paired NSW differences with their intervals.

    The top row shows each KPI over seeds per policy (box 25%-75%, whiskers 5%-95%, one
    point per seed); the bottom panel the paired NSW difference of each policy to the
    baseline with its bootstrap 95% interval, the numbers of the table
    (:func:`compare` computed them; nothing is resampled here). Drawn headless (Agg).

    Args:
        df: a :func:`compare` result (a frame read back from its CSV works too: without
            per-seed frames the top row shows means and 25%-75% ranges).
        path: write the figure here; the suffix picks the format: ``.png``, ``.svg`` or ``.pdf``
            (checked before drawing, :func:`check_plot_path`).

    Returns:
        The :class:`matplotlib.figure.Figure` (not registered with ``pyplot``).
    """
    if path is not None:
        check_plot_path(path)
    fig = comparison_figure(df)
    if path is not None:
        save_figure(fig, path)
    return fig


def comparison_cells(df: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """Header and text cells of a comparison table."""
    base = df.attrs.get("baseline", "baseline")
    n = len(df.attrs.get("seeds", []))
    header = ["Policy", *[KPI_LABELS[k] for k in KPI_NAMES], "NSW 95% CI", f"NSW - {base} (paired, 95% CI)",
              f"wins / {n}"]
    rows = []
    for _, r in df.iterrows():
        cells = [r["policy"], *[format_kpi(r[k], r[f"{k}_q25"], r[f"{k}_q75"]) for k in KPI_NAMES],
                 f"[{r['nsw_ci_low']:.3f}, {r['nsw_ci_high']:.3f}]"]
        if r["policy"] == base:
            cells += ["(baseline)", "-"]
        else:
            cells += [f"{r['nsw_diff']:+.4f} [{r['nsw_diff_low']:+.4f}, {r['nsw_diff_high']:+.4f}]", str(r["wins"])]
        rows.append(cells)
    return header, rows


def format_comparison(df: pd.DataFrame, fmt: str = "table") -> str:
    """A :func:`compare` result as text: ``"table"`` (aligned), ``"md"`` (markdown) or ``"csv"`` (every column)."""
    header, rows = comparison_cells(df)
    if fmt == "csv":
        return df.to_csv(index=False)
    if fmt == "md":
        return markdown_table(header, rows)
    return text_table(header, rows)


@dataclass(frozen=True)
class SuiteComparison:
    """Several policies over a suite's scenarios on the same seeds.

    Attributes:
        table: one row per (scenario, policy): ``scenario``, ``split``, ``policy``, mean ``nsw`` and
            ``normalized``, the paired normalized difference to the baseline with its bootstrap 95%
            interval (``diff``, ``diff_low``, ``diff_high``) and ``wins`` (seeds where the policy
            scores above the baseline).
        aggregates: split -> :class:`wfbench.analysis.aggregate.Aggregate`, with the probability of
            improvement over the baseline.
        runs: policy -> :func:`wfbench.evaluate_suite` frame (per scenario and seed).
        baseline: the baseline's name.
        baseline_added: whether the baseline was not among the policies and was added first.
        seeds: the seeds every policy ran on, in every scenario.
    """

    table: pd.DataFrame
    aggregates: dict[str, Any]
    runs: dict[str, pd.DataFrame]
    baseline: str
    baseline_added: bool
    seeds: list[int] = field(default_factory=list)


def suite_comparison_cells(result: SuiteComparison) -> tuple[list[str], list[list[str]]]:
    """Header and text cells of a suite comparison's table: a row per (scenario, policy)."""
    header = ["Scenario", "Split", "Policy", "NSW", "Normalized", f"- {result.baseline} (paired, 95% CI)",
              f"wins / {len(result.seeds)}"]
    rows = [[r["scenario"], r["split"], r["policy"], f"{r['nsw']:.4f}", f"{r['normalized']:.3f}",
             "(baseline)" if r["policy"] == result.baseline else
             f"{r['diff']:+.3f} [{r['diff_low']:+.3f}, {r['diff_high']:+.3f}]",
             "-" if r["policy"] == result.baseline else str(r["wins"])] for _, r in result.table.iterrows()]
    return header, rows


def format_suite_comparison(result: SuiteComparison, fmt: str = "table") -> str:
    """A :func:`compare_suite` result's per-scenario table as text: ``"table"``, ``"md"`` or ``"csv"`` (every column).

    The aggregate per split is :func:`wfbench.analysis.aggregate.aggregate_cells` of ``result.aggregates``.
    """
    if fmt == "csv":
        return result.table.to_csv(index=False)
    return (markdown_table if fmt == "md" else text_table)(*suite_comparison_cells(result))


def compare_suite(policies: Sequence[Any], suite: Any = "suite-v1", seeds: int | str | Iterable[int] = "test",
                  baseline: str = "heuristic", split: str | None = None, *,
                  act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S, seed: int = 0, poi_reps: int = 1000,
                  execution: Execution | None = None) -> SuiteComparison:
    """Policies over a suite, paired per scenario and seed with a baseline, and aggregated per split.

    Every policy runs on every scenario of the suite (or of ``split``) on the same seeds
    (:func:`wfbench.evaluate_suite`), so each scenario's difference to the baseline is
    paired by seed; the aggregate over scenarios and the probability of improvement are
    :func:`wfbench.analysis.aggregate.aggregate_suite`'s, deterministic given ``seed``.

    Args:
        policies: registry names, ``module:attr`` entry points or policy objects.
        suite: a suite name (``"suite-v1"``) or :class:`wfbench.scenarios.Suite`.
        seeds: the seeds of every scenario (default the test set).
        baseline: the policy the differences and the improvement are taken over.
        split: ``"train"``, ``"heldout"`` or ``None`` for both.
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy (``None``: none).
        seed: the aggregate's bootstrap seed.
        poi_reps: bootstrap replications of the probability of improvement's interval.
        execution: where and how the episodes play, one
            :class:`~wfbench.harness.backends.Execution` (as for :func:`compare`); ``None``:
            serial, in this process.

    Returns:
        The :class:`SuiteComparison`.
    """
    from wfbench.analysis.aggregate import aggregate_suite
    from wfbench.harness.suite import evaluate_suite
    from wfbench.scenarios import get_suite

    run = check_execution(execution, SERIAL)
    s = get_suite(suite)
    s.ids(split)  # an unknown split fails before anything runs
    seed_list = resolve_seeds(seeds)
    added = baseline not in policies
    loaded = [load_policy(p, act_timeout_s) for p in ([baseline, *policies] if added else policies)]
    by_name = {lp.name: lp for lp in loaded}
    runs = {name: evaluate_suite(lp, s, seed_list, split=split, execution=run) for name, lp in by_name.items()}
    base = runs[baseline]
    rows = []
    for sc in dict.fromkeys(base["scenario"]):
        b = base.loc[base["scenario"] == sc, "normalized"].to_numpy()
        for name, df in runs.items():
            g = df[df["scenario"] == sc]
            x = g["normalized"].to_numpy()
            d = paired_difference(x, b)
            rows.append({"scenario": sc, "split": g["split"].iloc[0], "policy": name, "nsw": float(g["nsw"].mean()),
                         "normalized": float(x.mean()), "diff": d.estimate, "diff_low": d.low, "diff_high": d.high,
                         "wins": int((x > b).sum())})
    aggs = aggregate_suite(runs, baseline=baseline, seed=seed, poi_reps=poi_reps)
    return SuiteComparison(table=pd.DataFrame(rows), aggregates=aggs, runs=runs, baseline=baseline,
                           baseline_added=added, seeds=seed_list)
