"""Figures of a comparison: the KPIs per policy over seeds, and the paired NSW differences with their intervals.

The statistics are not computed here: the differences and their bootstrap 95% intervals
are the ones :func:`wfbench.harness.compare.compare` (and the leaderboard's ranking) already hold,
from :func:`wfbench.analysis.stats.paired_difference`. The figures are built on
:class:`matplotlib.figure.Figure` directly, not through ``pyplot``, so they draw headless
(Agg) whatever backend the caller uses, and matplotlib is imported only when a figure is
made: ``import wfbench`` stays light.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import BY_NAME, KPI_LABELS, KPI_NAMES, SCORE
from wfbench.core.seeds import describe

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FIGURE_FORMATS = ("png", "svg", "pdf")
HIGHER_IS_BETTER = "#55a868"
LOWER_IS_BETTER = "#c44e52"
UNDECIDED = "#8c8c8c"


def utilization_band(config: ScenarioConfig | None = None) -> tuple[float, float]:
    """The utilization band our NSW rewards in full (docs/metrics.md): target +- tolerance of ``config``.

    Without a config, the band of :class:`~wfbench.core.config.ScenarioConfig`'s defaults (every shipped scenario's).
    """
    target = ScenarioConfig.target_utilization if config is None else config.target_utilization
    tol = ScenarioConfig.utilization_tolerance if config is None else config.utilization_tolerance
    return target - tol, target + tol


def figure_format(path: str | Path) -> str:
    """The format a figure path asks for by its suffix (``png``, ``svg`` or ``pdf``); ValueError otherwise."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in FIGURE_FORMATS:
        got = f"suffix '.{suffix}'" if suffix else "no suffix"
        raise ValueError(f"figure {str(path)!r} has {got}; allowed: {', '.join('.' + f for f in FIGURE_FORMATS)}")
    return suffix


def new_figure(**kwargs: Any) -> Figure:
    """A figure not registered with ``pyplot``: drawn by Agg, never shown, freed with its last reference."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` in the format of ``path``'s suffix.

    SVG keeps its text as text (policy names stay searchable) and SVG and PDF carry no
    creation date, so the same figure gives the same file.
    """
    import matplotlib

    path = Path(path)
    fmt = figure_format(path)
    metadata = {"svg": {"Date": None}, "pdf": {"CreationDate": None}}.get(fmt)
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "wfbench"}):
        fig.savefig(path, format=fmt, dpi=dpi, metadata=metadata)
    return path


def draw_kpi_distribution(ax: Axes, data: Sequence[np.ndarray], names: Sequence[str], kpi: str,
                          band: tuple[float, float] | None = None) -> None:
    """Box (25%-75%, whiskers 5%-95%) and the per-seed points of one KPI, one column per policy.

    ``band``: the utilization band shaded behind the utilization panel (default: :func:`utilization_band`).
    """
    pos = np.arange(1, len(names) + 1)
    if BY_NAME[kpi].better == "band":
        ax.axhspan(*(band or utilization_band()), color="0.9", zorder=0)
    ax.boxplot(data, positions=pos, whis=(5, 95), showfliers=False, widths=0.6, medianprops={"color": "#dd8452"})
    rng = np.random.default_rng(0)  # the jitter only spreads the points; fixed so a figure is reproducible
    for p, x in zip(pos, data, strict=True):
        ax.scatter(p + rng.uniform(-0.18, 0.18, len(x)), x, s=6, color="#4c72b0", alpha=0.45, lw=0, zorder=3)
    ax.set_xticks(pos, names, rotation=30, ha="right", fontsize=8)
    ax.set_title(KPI_LABELS.get(kpi, kpi) + (" (higher is better)" if kpi == SCORE else ""), fontsize=10)


def draw_kpi_ranges(ax: Axes, mean: np.ndarray, q25: np.ndarray, q75: np.ndarray, names: Sequence[str],
                    kpi: str) -> None:
    """Mean with its 25%-75% range per policy: what a table holds when the per-seed values are not at hand."""
    pos = np.arange(1, len(names) + 1)
    if BY_NAME[kpi].better == "band":
        ax.axhspan(*utilization_band(), color="0.9", zorder=0)
    ax.errorbar(pos, mean, yerr=np.vstack([mean - q25, q75 - mean]), fmt="o", color="#4c72b0", capsize=4)
    ax.set_xticks(pos, names, rotation=30, ha="right", fontsize=8)
    ax.set_title(KPI_LABELS.get(kpi, kpi) + (" (higher is better)" if kpi == SCORE else ""), fontsize=10)


def draw_paired_differences(ax: Axes, names: Sequence[str], diff: Sequence[float], low: Sequence[float],
                            high: Sequence[float], baseline: str, notes: Sequence[str] | None = None) -> None:
    """One row per policy: the paired NSW difference to ``baseline`` and its 95% interval, given, not computed.

    Green: the interval lies above zero (better than the baseline); red: below it; gray:
    it contains zero. Each row is labelled with its policy, numbers and ``notes`` (e.g. wins).
    """
    d, lo, hi = (np.asarray(v, dtype=np.float64) for v in (diff, low, high))
    y = np.arange(len(names))[::-1]  # first policy on top
    colors = [HIGHER_IS_BETTER if a > 0 else LOWER_IS_BETTER if b < 0 else UNDECIDED for a, b in zip(lo, hi,
                                                                                                      strict=True)]
    ax.axvline(0.0, color="0.3", lw=1, zorder=1)
    for yi, di, a, b, c in zip(y, d, lo, hi, colors, strict=True):
        ax.errorbar(di, yi, xerr=[[di - a], [b - di]], fmt="o", color=c, capsize=5, lw=2, ms=6, zorder=3)
    labels = [f"{n}  {di:+.4f} [{a:+.4f}, {b:+.4f}]" + (f"  {notes[i]}" if notes and notes[i] else "")
              for i, (n, di, a, b) in enumerate(zip(names, d, lo, hi, strict=True))]
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_ylim(-0.7, len(names) - 0.3)
    left, right = min(float(lo.min()), 0.0), max(float(hi.max()), 0.0)
    pad = 0.08 * max(right - left, 1e-4)
    ax.set_xlim(left - pad, right + pad)
    ax.set_xlabel(f"NSW - {baseline}, paired by seed (bootstrap 95% interval)")
    ax.grid(axis="x", color="0.9", zorder=0)


def comparison_figure(df: pd.DataFrame) -> Figure:
    """The figure of a :func:`wfbench.harness.compare.compare` result.

    Top: each KPI's distribution over seeds per policy (box and per-seed points; from
    ``df.attrs["runs"]``, or the mean and 25%-75% range of the table when it has no
    per-seed frames, e.g. read back from CSV). Bottom: each policy's paired NSW
    difference to the baseline with its bootstrap 95% interval, as in the table.
    """
    if df.empty:
        raise ValueError("nothing to plot: the comparison has no rows")
    names = df["policy"].astype(str).tolist()
    runs = df.attrs.get("runs") or {}
    baseline = str(df.attrs.get("baseline", names[0]))
    seeds = df.attrs.get("seeds") or []
    fig = new_figure(figsize=(min(16.0, max(12.0, 0.5 * len(names) * len(KPI_NAMES) + 4)), 6.4 + 0.45 * len(names)),
                     layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[4.6, 1.8 + 0.45 * len(names)])  # own layouts: the long
    axes = top.subplots(1, len(KPI_NAMES))  # difference labels do not squeeze the KPI panels
    for ax, k in zip(axes, KPI_NAMES, strict=True):
        if all(n in runs for n in names):
            draw_kpi_distribution(ax, [runs[n][k].to_numpy() for n in names], names, k)
        else:
            draw_kpi_ranges(ax, df[k].to_numpy(float), df[f"{k}_q25"].to_numpy(float),
                            df[f"{k}_q75"].to_numpy(float), names, k)
    ax = bottom.subplots()
    others = df[df["policy"] != baseline]
    if len(others):
        n = len(seeds)
        notes = [f"wins {int(w)}/{n}" for w in others["wins"]] if "wins" in others and n else None
        draw_paired_differences(ax, others["policy"].astype(str).tolist(), others["nsw_diff"],
                                others["nsw_diff_low"], others["nsw_diff_high"], baseline, notes)
    else:
        ax.set_axis_off()
        ax.text(0.5, 0.5, f"only the baseline {baseline!r}: no differences to draw", ha="center", va="center")
    where = f"{df.attrs.get('scenario', '')}, seeds {describe(list(seeds))}" if seeds else df.attrs.get("scenario", "")
    fig.suptitle(f"{where}: KPIs per seed (boxes 25%-75%, whiskers 5%-95%; gray: utilization 0.75 +- 0.05) and "
                 f"paired NSW differences to {baseline}", fontsize=10)
    return fig
