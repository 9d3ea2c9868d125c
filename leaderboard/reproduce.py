"""Regenerate the paper's Table 2, Table 3 and Figure 3 with wfbench's model, and the oracle gap.

Each writes markdown and CSV (and PNG for the figure) into an output folder and
returns the text it prints. The paper's NSW is a cost (lower is better) and its
formulas do not reproduce its own numbers; ours (``docs/metrics.md``) is a welfare in [0, 1],
higher is better. So the tables put the paper's numbers beside ours and compare
orderings and trends, never values; docs/reproduction.md says what matches and why.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from policies.registry import LEARNED, learned_names
from wfbench.evaluation import KPI_LABELS, KPIS, evaluate, format_kpi, summarize
from wfbench.presets import TABLE2_CELLS, TABLE2_GRIDS, table2_name
from wfbench.tables import markdown_table

DIRECTION = ("Direction: our NSW is a welfare in [0, 1] (docs/metrics.md), higher is better; the paper's NSW "
             "column is a cost, lower is better. Compare orderings and trends, not values.")

# Paper, Table 2: NSW (a cost, lower is better) by grid and (facilities, personnel)
PAPER_TABLE2 = {
    32: (5.53, 3.16, 2.96, 2.91, 6.0),
    64: (6.37, 4.41, 3.12, 5.14, 6.73),
    128: (6.7, 6.05, 3.65, 6.37, 7.17),
    256: (6.86, 6.35, 4.57, 6.78, 7.25),
}

# Paper, Table 3 rows 1-7: (dispatch, workforce, positioning), then WC, PUR, AFD, NSW as printed
PAPER_TABLE3 = [
    ("1", "Random", "Random", "Random", "75 (59-95)", "0.6 (0.4-0.8)", "0.3 (0.2-0.4)", "5.9 (2.4-11.1)"),
    ("2", "Random", "Heuristic", "Heuristic", "57 (48-66)", "0.8 (0.5-0.9)", "0.3 (0.2-0.4)", "3.7 (1.8-5.7)"),
    ("3", "Heuristic", "Heuristic", "Random", "45 (35-57)", "0.6 (0.3-1)", "0.2 (0.1-0.4)", "4.9 (2-7.5)"),
    ("4", "Heuristic", "Heuristic", "Heuristic", "46 (42-50)", "0.6 (0.5-0.8)", "0.2 (0.2-0.3)", "4.1 (3-5.1)"),
    ("5", "PPO", "Heuristic", "Heuristic", "57 (51-61)", "0.7 (0.7-0.8)", "0.3 (0.3-0.4)", "3.5 (2.4-4.4)"),
    ("6", "PPO", "PPO", "PPO", "45 (37-55)", "0.7 (0.7-0.8)", "0.4 (0.3-0.4)", "3.1 (2.2-3.7)"),
    ("7", "IMPALA", "IMPALA", "IMPALA", "49 (40-56)", "0.6 (0.6-0.7)", "0.4 (0.3-0.5)", "3.1 (2.5-3.5)"),
]
# Our policy for each paper row; None: not built yet (the RL rows)
TABLE3_POLICIES = {"1": "random", "2": "random-dispatch", "3": "random-positioning", "4": "heuristic",
                   "5": "ppo-dispatch", "6": "ppo-joint", "7": "impala-joint"}  # the RL rows: docs/rl.md
SOLVER_ROWS = [("S1", "solver"), ("S2", "solver-dispatch"), ("S3", "solver-workforce"), ("S4", "solver-positioning")]
ORACLE_ROWS = [("O1", "oracle-dispatch"), ("O2", "oracle")]
# beyond the paper: the heuristic and solver composites with their parameters tuned on the public seeds
# (wfbench tune, policies/tuned/, docs/policies.md#tuning)
TUNED_ROWS = [("T1", "heuristic-tuned"), ("T2", "solver-tuned")]
TUNED_PARTS = {"heuristic-tuned": ("Heuristic (tuned)", "Heuristic (tuned)", "Heuristic (tuned)"),
               "solver-tuned": ("Assignment (tuned)", "Staffing (tuned)", "p-median (tuned)")}
ORACLE_PARTS = {"oracle-dispatch": ("Hindsight oracle", "Heuristic", "Heuristic"),
                "oracle": ("Hindsight oracle", "Hindsight oracle", "Hindsight oracle")}
SOLVER_PARTS = {"solver": ("Assignment", "Staffing", "p-median"), "solver-dispatch": ("Assignment", "Heuristic",
                "Heuristic"), "solver-workforce": ("Heuristic", "Staffing", "Heuristic"),
                "solver-positioning": ("Heuristic", "Heuristic", "p-median")}


@dataclass
class Output:
    text: str
    files: list[Path]


def _write(out: Path, stem: str, md: str, df: pd.DataFrame) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    md_path, csv_path = out / f"{stem}.md", out / f"{stem}.csv"
    md_path.write_text(md + "\n")
    df.to_csv(csv_path, index=False)
    return [md_path, csv_path]


Progress = Callable[[str], None] | None


def table2(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
           address: str | None = None, progress: Progress = None) -> Output:
    """20 cells: heuristic dispatch, no hiring or letting go, ``runs`` seeds each; the paper's trends checked."""
    seeds = list(range(runs))
    nsw: dict[tuple[int, int, int], float] = {}
    records = []
    for grid in TABLE2_GRIDS:
        for k, (f, s) in enumerate(TABLE2_CELLS):
            name = table2_name(grid, f, s)
            if progress:
                progress(name)
            df = evaluate("fixed-workforce", name, seeds, backend=backend, workers=workers, address=address)
            nsw[grid, f, s] = float(df["nsw"].mean())
            records.append({"grid": grid, "facilities": f, "personnel": s, "scenario": name, "runs": runs,
                            "nsw": nsw[grid, f, s], "nsw_q25": df["nsw"].quantile(0.25),
                            "nsw_q75": df["nsw"].quantile(0.75), "paper_nsw_cost": PAPER_TABLE2[grid][k]})
    header = ["Grid size", *[f"{f}F x {s}S" for f, s in TABLE2_CELLS]]
    rows = [[f"{g} x {g}", *[f"{nsw[g, f, s]:.3f} (paper {PAPER_TABLE2[g][k]:g})"
                             for k, (f, s) in enumerate(TABLE2_CELLS)]] for g in TABLE2_GRIDS]
    trends = table2_trends(nsw)
    md = "\n".join([
        f"Table 2: NSW (mean over {runs} runs), heuristic dispatch, fixed workforce (no hiring or letting go).",
        "", markdown_table(header, rows), "", DIRECTION, "", "Trends the paper states, checked here:", "",
        *[f"- {t}" for t in trends],
    ])
    return Output(md, _write(out, "table2", md, pd.DataFrame(records)))


def table2_trends(nsw: dict[tuple[int, int, int], float]) -> list[str]:
    """Each trend of the paper with how many of its pairwise comparisons hold here (higher NSW = better)."""
    def count(pairs: list[tuple[tuple, tuple]]) -> tuple[int, int]:
        return sum(nsw[b] > nsw[a] for a, b in pairs), len(pairs)  # b is expected better

    # more personnel is better for 25 facilities: 5S -> 10S -> 25S
    staff = [((g, 25, a), (g, 25, b)) for g in TABLE2_GRIDS for a, b in ((5, 10), (10, 25))]
    staff_grids = sum(nsw[g, 25, 5] < nsw[g, 25, 10] < nsw[g, 25, 25] for g in TABLE2_GRIDS)
    # more facilities is worse (25 personnel): 25F -> 50F -> 100F
    fac = [((g, b, 25), (g, a, 25)) for g in TABLE2_GRIDS for a, b in ((25, 50), (50, 100))]
    fac_grids = sum(nsw[g, 25, 25] > nsw[g, 50, 25] > nsw[g, 100, 25] for g in TABLE2_GRIDS)
    # a larger grid is worse, in every column
    grid = [((b, f, s), (a, f, s)) for f, s in TABLE2_CELLS for a, b in zip(TABLE2_GRIDS, TABLE2_GRIDS[1:],
                                                                              strict=False)]
    grid_cols = sum(all(nsw[a, f, s] > nsw[b, f, s] for a, b in zip(TABLE2_GRIDS, TABLE2_GRIDS[1:], strict=False))
                    for f, s in TABLE2_CELLS)
    out = []
    for text, (held, total), whole, unit, n_units in (
        ("More personnel is better for 25 facilities (5S < 10S < 25S)", count(staff), staff_grids, "grids", 4),
        ("More facilities is worse for 25 personnel (25F > 50F > 100F)", count(fac), fac_grids, "grids", 4),
        ("A larger grid is worse (32 > 64 > 128 > 256 in each column)", count(grid), grid_cols, "columns", 5),
    ):
        verdict = "holds" if held == total else ("does not hold" if held == 0 else "holds in part")
        out.append(f"{text}: {verdict} here: {held} of {total} pairwise comparisons, monotone in {whole} of "
                   f"{n_units} {unit}.")
    return out


def table3(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
           address: str | None = None, progress: Progress = None, solver_rows: bool = True,
           oracle_rows: bool = True, tuned_rows: bool = True) -> Output:
    """The paper's rows 1-4 (exactly its combinations), the solver rows and open rows for RL.

    Beyond the paper, rows T1-T2: the heuristic and solver composites tuned on the public
    seeds (``wfbench tune``; the files in ``policies/tuned/``).

    Then the hindsight oracles and the proven upper bound on NSW (docs/hindsight.md): not
    deployable, a reference.
    """
    seeds = list(range(runs))
    header = ["#", "Dispatch", "Workforce mgmt", "Positioning", *[KPI_LABELS[k] for k in KPIS],
              "Paper: WC / PUR / AFD / NSW (cost)"]
    rows, records = [], []
    def run(num: str, policy: str, parts: tuple[str, str, str], paper_text: str, paper_cell: str) -> None:
        if progress:
            progress(policy)
        summ = summarize(evaluate(policy, "paper-64", seeds, backend=backend, workers=workers, address=address))
        rows.append([num, *parts, *[format_kpi(*summ[k]) for k in KPIS], paper_cell])
        records.append({"row": num, "policy": policy, **{k: summ[k][0] for k in KPIS},
                        **{f"{k}_q25": summ[k][1] for k in KPIS}, **{f"{k}_q75": summ[k][2] for k in KPIS},
                        "paper": paper_text})

    for num, d, w, p, *paper in PAPER_TABLE3:
        policy = TABLE3_POLICIES[num]
        paper_text = " / ".join(paper)
        if policy in LEARNED and policy not in learned_names():  # a trained network whose file is not shipped
            rows.append([num, d, w, p, "not shipped yet (RL)", *["-"] * (len(KPIS) - 1), paper_text])
        else:
            run(num, policy, (d, w, p), paper_text, paper_text)
    if solver_rows:
        for num, policy in SOLVER_ROWS:
            run(num, policy, SOLVER_PARTS[policy], "", "(not in the paper)")
    if tuned_rows:
        for num, policy in TUNED_ROWS:
            run(num, policy, TUNED_PARTS[policy], "", "(beyond the paper: tuned on public seeds)")
    if oracle_rows:
        for num, policy in ORACLE_ROWS:
            run(num, policy, ORACLE_PARTS[policy], "", "(not in the paper; reads the future)")
        from wfbench.bound import score_upper_bound

        if progress:
            progress("bound")
        bound = score_upper_bound("paper-64", seeds)
        q25, q75 = np.percentile(bound, [25, 75])
        rows.append(["B", "Upper bound", "(proven, any policy)", "", *["-"] * (len(KPIS) - 1),
                     format_kpi(float(bound.mean()), q25, q75), "(not in the paper)"])
        records.append({"row": "B", "policy": "bound", "nsw": float(bound.mean()), "nsw_q25": q25, "nsw_q75": q75,
                        "paper": ""})
    md = "\n".join([
        f"Table 3: paper-64, seeds 0-{runs - 1}; KPIs mean (25%-75%) over runs. Rows 1-4 are the paper's "
        "combinations; rows 5-7 are the shipped ppo-dispatch, ppo-joint and impala-joint checkpoints "
        "(docs/rl.md; a row whose checkpoint is not shipped says so); S1-S4 are wfbench's solver rows; "
        "T1-T2 (beyond the paper) are the heuristic and solver composites with their parameters tuned on the "
        "public seeds 1000-1049 (wfbench tune, docs/policies.md); "
        "O1-O2 are hindsight oracles (they read the episode's future: not deployable) and B is a proven upper "
        "bound on NSW per seed (docs/hindsight.md).",
        "", markdown_table(header, rows), "", DIRECTION,
    ])
    return Output(md, _write(out, "table3", md, pd.DataFrame(records)))


FIGURE3_METHODS = ("random", "random-dispatch", "random-positioning", "heuristic", "solver")


def figure3(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
            address: str | None = None, progress: Progress = None,
            methods: tuple[str, ...] = FIGURE3_METHODS) -> Output:
    """Per-step 25th-75th percentile bands of WC, PUR and AFD over the episode, one column per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.state import METRICS

    seeds = list(range(runs))
    rows_kpi = ("workforce_cost", "utilization", "downtime")
    fig, axes = plt.subplots(3, len(methods), figsize=(3.2 * len(methods), 7.5), sharex=True, sharey="row",
                             squeeze=False)
    records = []
    for j, m in enumerate(methods):
        if progress:
            progress(m)
        _, series = evaluate(m, "paper-64", seeds, backend=backend, workers=workers, address=address,
                             return_series=True)
        t = np.arange(series.shape[1])
        for i, k in enumerate(rows_kpi):
            x = series[:, :, METRICS.index(k)].astype(np.float64)
            q25, q50, q75 = np.percentile(x, [25, 50, 75], axis=0)
            ax = axes[i, j]
            if k == "utilization":
                ax.axhspan(0.70, 0.80, color="0.85", zorder=0, label="0.75 +- 0.05")
            ax.fill_between(t, q25, q75, alpha=0.4, color="#4c72b0", lw=0)
            ax.plot(t, q50, color="#4c72b0", lw=1)
            if i == 0:
                ax.set_title(m)
            if j == 0:
                ax.set_ylabel(KPI_LABELS[k])
            if i == 2:
                ax.set_xlabel("step")
            for step in range(0, series.shape[1], 10):
                records.append({"method": m, "kpi": k, "step": step, "q25": q25[step], "median": q50[step],
                                "q75": q75[step]})
    fig.suptitle(f"paper-64, {runs} episodes: per-step median and 25%-75% band (gray: utilization 0.75 +- 0.05)")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    png = out / "figure3.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    md = "\n".join([
        f"Figure 3: per-step 25th-75th percentile bands of workforce cost, utilization and downtime over "
        f"{runs} episodes of paper-64, one column per method; the gray band is utilization 0.75 +- 0.05.",
        "", "![figure 3](figure3.png)", "",
        "figure3.csv holds the bands every 10 steps.",
    ])
    files = _write(out, "figure3", md, pd.DataFrame(records))
    return Output(md, [png, *files])


GAP_SCENARIOS = ("small", "paper-64", "nonstationary", "table2-g32-f25-s10")
GAP_METHODS = ("heuristic", "solver", "oracle")


def gap(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
        address: str | None = None, progress: Progress = None,
        scenarios: tuple[str, ...] = GAP_SCENARIOS) -> Output:
    """What deployable policies leave on the table: heuristic, solver, hindsight oracle and the proven bound.

    Per scenario, the mean NSW of each method over seeds 0..runs-1 with its bootstrap
    95% interval, the oracle's paired gain over the solver, and the mean upper bound
    (docs/hindsight.md). Writes gap.md, gap.csv, gap.png and gap.svg.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.bound import score_upper_bound
    from wfbench.stats import bootstrap_ci, paired_difference

    seeds = list(range(runs))
    records, rows, per_seed = [], [], {}
    for scenario in scenarios:
        for m in GAP_METHODS:
            if progress:
                progress(f"{scenario}: {m}")
            per_seed[scenario, m] = evaluate(m, scenario, seeds, backend=backend, workers=workers,
                                             address=address)["nsw"].to_numpy()
        per_seed[scenario, "bound"] = score_upper_bound(scenario, seeds)
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
    png, svg = out / "gap.png", out / "gap.svg"
    fig.savefig(png, dpi=110)
    fig.savefig(svg)
    plt.close(fig)
    header = ["Scenario", *GAP_METHODS, "Upper bound", "oracle - solver (paired, 95% CI)", "bound - best",
              "oracle / bound (mean per seed)"]
    md = "\n".join([
        f"The gap: mean NSW over seeds 0-{runs - 1} of the heuristic and solver composites (deployable), the "
        "hindsight oracle (reads the future) and the proven per-seed upper bound (docs/hindsight.md).",
        "", markdown_table(header, rows), "", "![the gap per scenario](gap.png)",
    ])
    return Output(md, [png, svg, *_write(out, "gap", md, df)])


TARGETS = {"table2": table2, "table3": table3, "figure3": figure3, "gap": gap}
