"""Figure 3: per-step KPI bands over the episode, the paper's methods beside the solver, tuned, RL and oracle ones."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.core.kpis import KPI_LABELS, MEASURED
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.policies.registry import LINEUPS, learned_names, names_of
from wfbench.reproduce.common import PROCESS, Output, Progress, write

# the methods of Figure 3, in groups drawn side by side; the paper's figure has the first group and PPO. The
# learned group holds every network of the registry (wfbench.policies.registry.names_of), drawn where it is shipped
FIGURE3_GROUPS = (
    ("Paper rows 1-4", ("random", "random-dispatch", "random-positioning", "heuristic")),
    ("Solvers and tuned", LINEUPS["figure3-solver"]),
    ("Learned (RL)", ("ppo-dispatch", "ppo-joint",
                      *[n for n in names_of("learned") if n not in ("ppo-dispatch", "ppo-joint")])),
    ("Hindsight oracles (read the future)", ("oracle-dispatch", "oracle")),
)
FIGURE3_METHODS = tuple(m for _, ms in FIGURE3_GROUPS for m in ms)
FIGURE3_REFERENCE = "heuristic"  # drawn dashed in every group, for comparison
FIGURE3_COLORS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3", "#8c8c8c")


def figure3_methods() -> tuple[str, ...]:
    """The methods Figure 3 draws here: all of :data:`FIGURE3_METHODS` but the learned ones not available.

    A learned policy (``wfbench.policies.registry.names_of("learned")``) needs its shipped checkpoint and torch.
    """
    import importlib.util

    have_torch = importlib.util.find_spec("torch") is not None
    available = set(learned_names()) if have_torch else set()
    return tuple(m for m in FIGURE3_METHODS if m not in names_of("learned") or m in available)


def size(methods: tuple[str, ...] | None = None) -> int:
    """The methods :func:`figure3` evaluates (for a progress bar)."""
    return len(figure3_methods() if methods is None else methods)


def figure3(out: Path, runs: int = 50, execution: Execution = PROCESS, progress: Progress = None,
            methods: tuple[str, ...] | None = None) -> Output:
    """Per-step KPI bands over the episode: the paper's methods beside the solver, tuned, RL and oracle ones.

    One column per group of :data:`FIGURE3_GROUPS` (a method outside them gets a group of
    its own), one row per KPI (workforce cost, utilization, downtime); each method of a
    group is its per-step median and 25th-75th percentile band over ``runs`` episodes of
    paper-64, and the heuristic is drawn dashed in every group. ``methods`` defaults to
    :func:`figure3_methods` (the learned ones only where their checkpoint and torch are).
    Writes figure3.png, figure3.svg, figure3.md and figure3.csv (the bands every 10 steps).
    """
    from wfbench.analysis.plots import new_figure, save_figure, utilization_band
    from wfbench.core.config import ScenarioConfig
    from wfbench.core.kpis import BY_NAME
    from wfbench.core.state import METRICS

    methods = figure3_methods() if methods is None else tuple(methods)
    grouped = [(title, tuple(m for m in ms if m in methods)) for title, ms in FIGURE3_GROUPS]
    grouped = [(t, ms) for t, ms in grouped if ms]
    known = {m for _, ms in FIGURE3_GROUPS for m in ms}
    grouped += [("Other", tuple(m for m in methods if m not in known))] if set(methods) - known else []
    seeds = list(range(runs))
    rows_kpi = MEASURED  # one row of panels per measured KPI (the score is their welfare)
    fig = new_figure(figsize=(4.4 * len(grouped), 8.2), layout="constrained")
    axes = fig.subplots(len(rows_kpi), len(grouped), sharex=True, sharey="row", squeeze=False)
    records = []
    bands: dict[str, list[np.ndarray]] = {}
    for m in dict.fromkeys([*methods, *([FIGURE3_REFERENCE] if len(grouped) > 1 else [])]):
        if progress:
            progress(m)
        _, series = evaluate(m, "paper-64", seeds, return_series=True, execution=execution)
        bands[m] = []
        for k in rows_kpi:
            q = np.percentile(series[:, :, METRICS.index(k)].astype(np.float64), [25, 50, 75], axis=0)
            bands[m].append(q)
            if m in methods:
                records += [{"method": m, "kpi": k, "step": step, "q25": q[0, step], "median": q[1, step],
                             "q75": q[2, step]} for step in range(0, q.shape[1], 10)]
    for j, (title, ms) in enumerate(grouped):
        for i, k in enumerate(rows_kpi):
            ax = axes[i, j]
            if BY_NAME[k].better == "band":
                ax.axhspan(*utilization_band(ScenarioConfig.preset("paper-64")), color="0.9", zorder=0)
            if FIGURE3_REFERENCE in bands and FIGURE3_REFERENCE not in ms:
                ref = bands[FIGURE3_REFERENCE][i][1]
                ax.plot(np.arange(ref.size), ref, color="0.35", ls="--", lw=1,
                        label=f"{FIGURE3_REFERENCE} (median)")
            for m, c in zip(ms, FIGURE3_COLORS, strict=False):
                q25, q50, q75 = bands[m][i]
                t = np.arange(q50.size)
                ax.fill_between(t, q25, q75, alpha=0.25, color=c, lw=0)
                ax.plot(t, q50, color=c, lw=1.2, label=m)
            if i == 0:
                ax.set_title(title, fontsize=10)
            if j == 0:
                ax.set_ylabel(KPI_LABELS[k])
            if i == len(rows_kpi) - 1:
                ax.set_xlabel("step")
                ax.legend(*axes[0, j].get_legend_handles_labels(), fontsize=8, ncols=2, loc="upper center",
                          bbox_to_anchor=(0.5, -0.22), frameon=False)  # below the panels: it hides no band
    fig.suptitle(f"paper-64, {runs} episodes: per-step median and 25%-75% band per method (dashed: the "
                 f"{FIGURE3_REFERENCE}'s median; gray: utilization 0.75 +- 0.05)", fontsize=10)
    out.mkdir(parents=True, exist_ok=True)
    png, svg = save_figure(fig, out / "figure3.png"), save_figure(fig, out / "figure3.svg")
    listed = "; ".join(f"{t}: {', '.join(ms)}" for t, ms in grouped)
    md = "\n".join([
        f"Figure 3: per-step median and 25th-75th percentile band of workforce cost, utilization and downtime over "
        f"{runs} episodes of paper-64, one column per group of methods ({listed}); the {FIGURE3_REFERENCE}'s "
        "median is dashed in the other groups, the gray band is utilization 0.75 +- 0.05.",
        "", "![figure 3](figure3.png)", "",
        "figure3.csv holds the bands every 10 steps; figure3.svg is the same figure as SVG.",
    ])
    files = write(out, "figure3", md, pd.DataFrame(records))
    return Output(md, [png, svg, *files])
