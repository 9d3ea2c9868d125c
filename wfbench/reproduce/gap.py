"""The gap: what deployable policies leave on the table, beside the hindsight oracle and the proven bound."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.analysis.tables import markdown_table
from wfbench.core.kpis import SCORE
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.policies.registry import LINEUPS
from wfbench.reproduce.common import PROCESS, Output, Progress, write
from wfbench.scenarios.resolve import resolve_scenario

GAP_SCENARIOS = ("small", "paper-64", "nonstationary", "table2-g32-f25-s10")
GAP_METHODS = LINEUPS["gap"]  # the registry's lineups


def size(scenarios: tuple[str, ...] = GAP_SCENARIOS) -> int:
    """The evaluations :func:`gap` runs (for a progress bar): each method on each scenario."""
    return len(scenarios) * len(GAP_METHODS)


def gap(out: Path, runs: int = 50, execution: Execution = PROCESS, progress: Progress = None,
        scenarios: tuple[str, ...] = GAP_SCENARIOS) -> Output:
    """What deployable policies leave on the table: heuristic, solver, hindsight oracle and the proven bound.

    Per scenario, the mean NSW of each method over seeds 0..runs-1 with its bootstrap
    95% interval, the oracle's paired gain over the solver, and the mean upper bound
    (docs/hindsight.md). Writes gap.md, gap.csv, gap.png and gap.svg.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.analysis.plots import save_figure
    from wfbench.analysis.stats import bootstrap_ci, paired_difference
    from wfbench.core.bound import score_upper_bound

    seeds = list(range(runs))
    records, rows, per_seed = [], [], {}
    for scenario in scenarios:
        config = resolve_scenario(scenario)  # once: the evaluations and the bound share it
        for m in GAP_METHODS:
            if progress:
                progress(f"{scenario}: {m}")
            per_seed[scenario, m] = evaluate(m, config, seeds, execution=execution)[SCORE].to_numpy()
        per_seed[scenario, "bound"] = score_upper_bound(config, seeds)
        for m in (*GAP_METHODS, "bound"):
            x = per_seed[scenario, m]
            ci = bootstrap_ci(x)
            records.append({"scenario": scenario, "method": m, "nsw": float(x.mean()), "ci_low": ci.low,
                            "ci_high": ci.high})
        d = paired_difference(per_seed[scenario, "oracle"], per_seed[scenario, "solver"])
        best = max(per_seed[scenario, m].mean() for m in GAP_METHODS)
        rows.append([scenario, *[f"{per_seed[scenario, m].mean():.4f}" for m in (*GAP_METHODS, "bound")],
                     f"{d[0]:+.4f} [{d[1]:+.4f}, {d[2]:+.4f}]",
                     f"{per_seed[scenario, 'bound'].mean() - best:.4f}",
                     f"{(per_seed[scenario, 'oracle'] / per_seed[scenario, 'bound']).mean():.1%}"])
    df = pd.DataFrame(records)
    fig, ax = plt.subplots(figsize=(1.9 * len(scenarios) + 2, 4))
    colors = {"heuristic": "#8c8c8c", "solver": "#4c72b0", "oracle": "#dd8452", "bound": "#55a868"}
    width = 0.2
    for k, m in enumerate((*GAP_METHODS, "bound")):
        sub = df[df["method"] == m]
        x = np.arange(len(scenarios)) + (k - 1.5) * width
        err = np.vstack([sub["nsw"] - sub["ci_low"], sub["ci_high"] - sub["nsw"]])
        ax.bar(x, sub["nsw"], width, yerr=err, capsize=2, color=colors[m],
               label="upper bound (proven)" if m == "bound" else m, hatch="//" if m == "bound" else None,
               edgecolor="white" if m != "bound" else "#2d6a3e")
    ax.set_xticks(np.arange(len(scenarios)), scenarios)
    ax.set_ylabel("mean NSW (higher is better)")
    lo = float(df["ci_low"].min())
    ax.set_ylim(max(0.0, lo - 0.1), min(1.0, float(df["ci_high"].max()) + 0.05))
    ax.set_title(f"What deployable policies leave on the table: seeds 0-{runs - 1}, 95% intervals")
    ax.legend(ncols=4, loc="upper center", bbox_to_anchor=(0.5, -0.12), frameon=False)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    # save_figure: an SVG without a creation date and with fixed ids, so the same numbers give the same file
    png, svg = save_figure(fig, out / "gap.png"), save_figure(fig, out / "gap.svg")
    plt.close(fig)
    header = ["Scenario", *GAP_METHODS, "Upper bound", "oracle - solver (paired, 95% CI)", "bound - best",
              "oracle / bound (mean per seed)"]
    md = "\n".join([
        f"The gap: mean NSW over seeds 0-{runs - 1} of the heuristic and solver composites (deployable), the "
        "hindsight oracle (reads the future) and the proven per-seed upper bound (docs/hindsight.md).",
        "", markdown_table(header, rows), "", "![the gap per scenario](gap.png)",
    ])
    return Output(md, [png, svg, *write(out, "gap", md, df)])
