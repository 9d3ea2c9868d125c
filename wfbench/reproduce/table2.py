"""Table 2: heuristic dispatch with a fixed workforce on 20 cells (grid x facilities x personnel).

The paper's trends (more personnel is better, more facilities and a larger grid are
worse) are counted pair by pair, for NSW and for each KPI alone in its own direction
(:func:`wfbench.core.kpis.kpi_score`), since utilization sits inside our NSW and pulls
against downtime.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from wfbench.analysis.tables import markdown_table
from wfbench.core.kpis import KPI_LABELS, KPI_NAMES, MEASURED, SCORE, better_text, kpi_score
from wfbench.core.presets import TABLE2_CELLS, TABLE2_GRIDS, table2_name
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.reproduce.common import DIRECTION, PROCESS, Output, Progress, write
from wfbench.reproduce.paper import table2_nsw_cost
from wfbench.scenarios.resolve import resolve_scenario

TREND_KPIS = (SCORE, *reversed(MEASURED))
"""The KPIs whose trends are counted, in the order of the rows and panels: the score, then the measured ones."""

# each trend of the paper as chains of cells, each chain ordered from the cell expected worst to the one expected
# best; one pairwise comparison per consecutive pair; (key, text, unit the chains run in)
TABLE2_TRENDS = (
    ("personnel", "More personnel is better for 25 facilities (5S < 10S < 25S)", "grids"),
    ("facilities", "More facilities is worse for 25 personnel (25F > 50F > 100F)", "grids"),
    ("grid", "A larger grid is worse (32 > 64 > 128 > 256 in each column)", "columns"),
)


class TrendCount(NamedTuple):
    trend: str  # a key of TABLE2_TRENDS
    held: int  # pairwise comparisons that go the paper's way
    total: int
    monotone: int  # chains (grids or columns) where every comparison holds
    chains: int
    ties: int = 0  # comparisons with equal values: neither held nor broken (workforce cost with a fixed workforce)

    def cell(self) -> str:
        unit = dict((k, u) for k, _, u in TABLE2_TRENDS)[self.trend]
        tied = f", {self.ties} tied" if self.ties else ""
        return f"{self.held}/{self.total}{tied} (monotone in {self.monotone}/{self.chains} {unit})"


def _trend_chains(trend: str) -> list[list[tuple[int, int, int]]]:
    if trend == "personnel":
        return [[(g, 25, s) for s in (5, 10, 25)] for g in TABLE2_GRIDS]
    if trend == "facilities":
        return [[(g, f, 25) for f in (100, 50, 25)] for g in TABLE2_GRIDS]
    return [[(g, f, s) for g in reversed(TABLE2_GRIDS)] for f, s in TABLE2_CELLS]


def table2_trend_counts(score: dict[tuple[int, int, int], float]) -> list[TrendCount]:
    """How many pairwise comparisons of each of the paper's trends hold, ``score`` higher = better."""
    out = []
    for key, _, _ in TABLE2_TRENDS:
        chains = _trend_chains(key)
        ok = [[score[b] > score[a] for a, b in zip(c, c[1:], strict=False)] for c in chains]
        ties = sum(score[b] == score[a] for c in chains for a, b in zip(c, c[1:], strict=False))
        out.append(TrendCount(key, sum(map(sum, ok)), sum(map(len, ok)), sum(map(all, ok)), len(chains), ties))
    return out


def table2_trends_per_kpi(values: dict[str, dict[tuple[int, int, int], float]],
                          target_utilization: float = 0.75) -> dict[str, list[TrendCount]]:
    """The trend counts of every KPI in ``values`` (KPI -> cell -> mean), each judged in its own direction."""
    return {k: table2_trend_counts({c: kpi_score(k, v, target_utilization) for c, v in cells.items()})
            for k, cells in values.items()}


def table2_trends(nsw: dict[tuple[int, int, int], float]) -> list[str]:
    """Each trend of the paper with how many of its pairwise comparisons hold here (higher NSW = better)."""
    out = []
    for (_, text, unit), t in zip(TABLE2_TRENDS, table2_trend_counts(nsw), strict=True):
        verdict = "holds" if t.held == t.total else ("does not hold" if t.held == 0 else "holds in part")
        out.append(f"{text}: {verdict} here: {t.held} of {t.total} pairwise comparisons, monotone in {t.monotone} "
                   f"of {t.chains} {unit}.")
    return out


def size() -> int:
    """The evaluations :func:`table2` runs (for a progress bar): one per cell."""
    return len(TABLE2_GRIDS) * len(TABLE2_CELLS)


def table2(out: Path, runs: int = 50, execution: Execution = PROCESS, progress: Progress = None) -> Output:
    """20 cells: heuristic dispatch, no hiring or letting go, ``runs`` seeds each; the paper's trends checked.

    The trends are counted for NSW and for each KPI alone (:func:`wfbench.core.kpis.better_text`
    says which way is better), since utilization sits inside our NSW and pulls against
    downtime. Writes table2.md, table2.csv (every KPI per cell), table2_trends.csv
    (the counts per KPI and trend) and the figure table2.png / table2.svg.
    """
    paper = table2_nsw_cost()
    seeds = list(range(runs))
    values: dict[str, dict[tuple[int, int, int], float]] = {k: {} for k in TREND_KPIS}
    records = []
    for grid in TABLE2_GRIDS:
        for k, (f, s) in enumerate(TABLE2_CELLS):
            name = table2_name(grid, f, s)
            if progress:
                progress(name)
            df = evaluate("fixed-workforce", name, seeds, execution=execution)
            rec = {"grid": grid, "facilities": f, "personnel": s, "scenario": name, "runs": runs}
            for kpi in KPI_NAMES:
                values.setdefault(kpi, {})[grid, f, s] = float(df[kpi].mean())
                rec.update({kpi: float(df[kpi].mean()), f"{kpi}_q25": df[kpi].quantile(0.25),
                            f"{kpi}_q75": df[kpi].quantile(0.75)})
            records.append({**rec, "paper_nsw_cost": paper[grid][k]})
    cell_config = resolve_scenario(table2_name(TABLE2_GRIDS[0], *TABLE2_CELLS[0]))
    target = cell_config.target_utilization
    better = {k: better_text(k, target) for k in TREND_KPIS}
    nsw = values[SCORE]
    header = ["Grid size", *[f"{f}F x {s}S" for f, s in TABLE2_CELLS]]
    rows = [[f"{g} x {g}", *[f"{nsw[g, f, s]:.3f} (paper {paper[g][k]:g})"
                             for k, (f, s) in enumerate(TABLE2_CELLS)]] for g in TABLE2_GRIDS]
    trends = table2_trends(nsw)
    per_kpi = table2_trends_per_kpi({k: values[k] for k in TREND_KPIS}, target)
    texts = {k: t for k, t, _ in TABLE2_TRENDS}
    kpi_header = ["KPI (better is)", *[texts[k] for k, _, _ in TABLE2_TRENDS]]
    kpi_rows = [[f"{KPI_LABELS[k]} ({better[k]})", *[c.cell() for c in per_kpi[k]]] for k in TREND_KPIS]
    kpi_tables = []
    for kpi in TREND_KPIS:
        if kpi == SCORE:  # the score is the table above
            continue
        kpi_tables += ["", f"{KPI_LABELS[kpi]} (mean over {runs} runs; better is {better[kpi]}):", "",
                       markdown_table(header, [[f"{g} x {g}", *[f"{values[kpi][g, f, s]:.3g}" for f, s in
                                                                 TABLE2_CELLS]] for g in TABLE2_GRIDS])]
    md = "\n".join([
        f"Table 2: NSW (mean over {runs} runs), heuristic dispatch, fixed workforce (no hiring or letting go).",
        "", markdown_table(header, rows), "", DIRECTION, "", "Trends the paper states, checked here:", "",
        *[f"- {t}" for t in trends],
        "", "The same trends per KPI, each KPI judged alone in its own direction (pairwise comparisons that hold; "
        "utilization: closer to the target is better; a tie neither holds nor breaks a trend):", "",
        markdown_table(kpi_header, kpi_rows),
        *kpi_tables, "", "![table 2 per KPI](table2.png)",
    ])
    trend_records = [{"kpi": k, "better": better[k], **c._asdict()} for k in TREND_KPIS for c in per_kpi[k]]
    files = write(out, "table2", md, pd.DataFrame(records))
    trends_csv = out / "table2_trends.csv"
    pd.DataFrame(trend_records).to_csv(trends_csv, index=False)
    figs = _figure(out, values, per_kpi, better, runs, cell_config)
    return Output(md, [*files, trends_csv, *figs])


def _figure(out: Path, values: dict[str, dict[tuple[int, int, int], float]], per_kpi: dict[str, list[TrendCount]],
            better: dict[str, str], runs: int, config) -> list[Path]:
    from wfbench.analysis.plots import new_figure, save_figure, utilization_band
    from wfbench.core.kpis import BY_NAME

    fig = new_figure(figsize=(4.6 * len(TREND_KPIS), 4.4), layout="constrained")
    axes = fig.subplots(1, len(TREND_KPIS))
    x = np.arange(len(TABLE2_CELLS))
    colors = ("#4c72b0", "#55a868", "#dd8452", "#c44e52")
    for ax, kpi in zip(axes, TREND_KPIS, strict=True):
        if BY_NAME[kpi].better == "band":
            ax.axhspan(*utilization_band(config), color="0.9", zorder=0)
            ax.axhline(config.target_utilization, color="0.6", ls="--", lw=1)
        for g, c in zip(TABLE2_GRIDS, colors, strict=True):
            ax.plot(x, [values[kpi][g, f, s] for f, s in TABLE2_CELLS], "o-", color=c, label=f"{g} x {g}")
        ax.set_xticks(x, [f"{f}F x {s}S" for f, s in TABLE2_CELLS], rotation=30, ha="right", fontsize=8)
        counts = ", ".join(f"{t.trend} {t.held}/{t.total}" + (f" ({t.ties} tied)" if t.ties else "")
                           for t in per_kpi[kpi])
        ax.set_title(f"{KPI_LABELS[kpi]} ({better[kpi]} is better)\ntrends hold: {counts}", fontsize=8.5)
    axes[0].legend(title="grid", fontsize=8)
    fig.suptitle(f"Table 2 per KPI: heuristic dispatch, fixed workforce, mean over {runs} runs per cell",
                 fontsize=10)
    return [save_figure(fig, out / "table2.png"), save_figure(fig, out / "table2.svg")]
