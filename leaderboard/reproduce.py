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
from typing import NamedTuple

import numpy as np
import pandas as pd

from policies.registry import LEARNED, learned_names
from wfbench.core.presets import TABLE2_CELLS, TABLE2_GRIDS, table2_name
from wfbench.evaluation import KPI_LABELS, KPIS, evaluate, format_kpi, summarize
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
# beyond the paper: the shipped networks that are not rows 5-7 (docs/rl.md, docs/hindsight-learning.md); a row
# whose checkpoint is not shipped says so, like rows 5-7
LEARNED_ROWS = [("L1", "ppo-independent"), ("L2", "hindsight-joint"), ("L3", "hindsight-ppo")]
LEARNED_PARTS = {"ppo-independent": ("PPO (own net)", "PPO (own net)", "PPO (own net)"),
                 "hindsight-joint": ("Hindsight learning", "Hindsight learning", "Hindsight learning"),
                 "hindsight-ppo": ("PPO", "PPO + hindsight learning", "PPO")}
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


TREND_KPIS = ("nsw", "downtime", "utilization", "workforce_cost")
TREND_BETTER = {"nsw": "higher", "downtime": "lower", "workforce_cost": "lower",
                "utilization": "closer to the target 0.75"}
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


def kpi_score(kpi: str, value: float, target_utilization: float = 0.75) -> float:
    """A KPI as a score where higher is better.

    NSW as it is, workforce cost and downtime negated, utilization as minus its distance
    to the target (the centre of the band our NSW rewards).
    """
    if kpi == "nsw":
        return value
    if kpi in ("workforce_cost", "downtime"):
        return -value
    if kpi == "utilization":
        return -abs(value - target_utilization)
    raise ValueError(f"unknown KPI {kpi!r}; allowed: {', '.join(TREND_KPIS)}")


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


def table2(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
           address: str | None = None, progress: Progress = None) -> Output:
    """20 cells: heuristic dispatch, no hiring or letting go, ``runs`` seeds each; the paper's trends checked.

    The trends are counted for NSW and for each KPI alone (:data:`TREND_BETTER` says
    which way is better), since utilization sits inside our NSW and pulls against
    downtime. Writes table2.md, table2.csv (every KPI per cell), table2_trends.csv
    (the counts per KPI and trend) and the figure table2.png / table2.svg.
    """
    from wfbench.core.config import ScenarioConfig

    seeds = list(range(runs))
    values: dict[str, dict[tuple[int, int, int], float]] = {k: {} for k in TREND_KPIS}
    records = []
    for grid in TABLE2_GRIDS:
        for k, (f, s) in enumerate(TABLE2_CELLS):
            name = table2_name(grid, f, s)
            if progress:
                progress(name)
            df = evaluate("fixed-workforce", name, seeds, backend=backend, workers=workers, address=address)
            rec = {"grid": grid, "facilities": f, "personnel": s, "scenario": name, "runs": runs}
            for kpi in KPIS:
                values.setdefault(kpi, {})[grid, f, s] = float(df[kpi].mean())
                rec.update({kpi: float(df[kpi].mean()), f"{kpi}_q25": df[kpi].quantile(0.25),
                            f"{kpi}_q75": df[kpi].quantile(0.75)})
            records.append({**rec, "paper_nsw_cost": PAPER_TABLE2[grid][k]})
    cell_config = ScenarioConfig.resolve(table2_name(TABLE2_GRIDS[0], *TABLE2_CELLS[0]))
    target = cell_config.target_utilization
    nsw = values["nsw"]
    header = ["Grid size", *[f"{f}F x {s}S" for f, s in TABLE2_CELLS]]
    rows = [[f"{g} x {g}", *[f"{nsw[g, f, s]:.3f} (paper {PAPER_TABLE2[g][k]:g})"
                             for k, (f, s) in enumerate(TABLE2_CELLS)]] for g in TABLE2_GRIDS]
    trends = table2_trends(nsw)
    per_kpi = table2_trends_per_kpi({k: values[k] for k in TREND_KPIS}, target)
    texts = {k: t for k, t, _ in TABLE2_TRENDS}
    kpi_header = ["KPI (better is)", *[texts[k] for k, _, _ in TABLE2_TRENDS]]
    kpi_rows = [[f"{KPI_LABELS[k]} ({TREND_BETTER[k]})", *[c.cell() for c in per_kpi[k]]] for k in TREND_KPIS]
    other = [kpi for kpi in TREND_KPIS if kpi != "nsw"]
    kpi_tables = []
    for kpi in other:
        kpi_tables += ["", f"{KPI_LABELS[kpi]} (mean over {runs} runs; better is {TREND_BETTER[kpi]}):", "",
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
    trend_records = [{"kpi": k, "better": TREND_BETTER[k], **c._asdict()} for k in TREND_KPIS for c in per_kpi[k]]
    files = _write(out, "table2", md, pd.DataFrame(records))
    trends_csv = out / "table2_trends.csv"
    pd.DataFrame(trend_records).to_csv(trends_csv, index=False)
    figs = _table2_figure(out, values, per_kpi, runs, cell_config)
    return Output(md, [*files, trends_csv, *figs])


def _table2_figure(out: Path, values: dict[str, dict[tuple[int, int, int], float]],
                   per_kpi: dict[str, list[TrendCount]], runs: int, config) -> list[Path]:
    from wfbench.plots import new_figure, save_figure, utilization_band

    fig = new_figure(figsize=(4.6 * len(TREND_KPIS), 4.4), layout="constrained")
    axes = fig.subplots(1, len(TREND_KPIS))
    x = np.arange(len(TABLE2_CELLS))
    colors = ("#4c72b0", "#55a868", "#dd8452", "#c44e52")
    for ax, kpi in zip(axes, TREND_KPIS, strict=True):
        if kpi == "utilization":
            ax.axhspan(*utilization_band(config), color="0.9", zorder=0)
            ax.axhline(config.target_utilization, color="0.6", ls="--", lw=1)
        for g, c in zip(TABLE2_GRIDS, colors, strict=True):
            ax.plot(x, [values[kpi][g, f, s] for f, s in TABLE2_CELLS], "o-", color=c, label=f"{g} x {g}")
        ax.set_xticks(x, [f"{f}F x {s}S" for f, s in TABLE2_CELLS], rotation=30, ha="right", fontsize=8)
        counts = ", ".join(f"{t.trend} {t.held}/{t.total}" + (f" ({t.ties} tied)" if t.ties else "")
                           for t in per_kpi[kpi])
        ax.set_title(f"{KPI_LABELS[kpi]} ({TREND_BETTER[kpi]} is better)\ntrends hold: {counts}", fontsize=8.5)
    axes[0].legend(title="grid", fontsize=8)
    fig.suptitle(f"Table 2 per KPI: heuristic dispatch, fixed workforce, mean over {runs} runs per cell",
                 fontsize=10)
    paths = [save_figure(fig, out / "table2.png"), save_figure(fig, out / "table2.svg")]
    return paths


def table2_trends(nsw: dict[tuple[int, int, int], float]) -> list[str]:
    """Each trend of the paper with how many of its pairwise comparisons hold here (higher NSW = better)."""
    out = []
    for (_, text, unit), t in zip(TABLE2_TRENDS, table2_trend_counts(nsw), strict=True):
        verdict = "holds" if t.held == t.total else ("does not hold" if t.held == 0 else "holds in part")
        out.append(f"{text}: {verdict} here: {t.held} of {t.total} pairwise comparisons, monotone in {t.monotone} "
                   f"of {t.chains} {unit}.")
    return out


def table3_size() -> int:
    """The evaluations :func:`table3` runs with its default rows (for a progress bar): rows, tuned, oracles, bound."""
    shipped = [n for n, *_ in PAPER_TABLE3
               if TABLE3_POLICIES[n] not in LEARNED or TABLE3_POLICIES[n] in learned_names()]
    learned = [n for _, n in LEARNED_ROWS if n in learned_names()]
    return len(shipped) + len(SOLVER_ROWS) + len(TUNED_ROWS) + len(learned) + len(ORACLE_ROWS) + 1


def table3(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
           address: str | None = None, progress: Progress = None, solver_rows: bool = True,
           oracle_rows: bool = True, tuned_rows: bool = True, learned_rows: bool = True) -> Output:
    """The paper's rows 1-4 (exactly its combinations), the solver rows and the RL rows 5-7.

    Beyond the paper, rows T1-T2: the heuristic and solver composites tuned on the public
    seeds (``wfbench tune``; the files in ``policies/tuned/``); rows L1-L3: the other
    shipped networks (independent agents, hindsight learning, PPO improved by hindsight
    learning).

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

    def not_shipped(num: str, parts: tuple[str, str, str], paper_cell: str) -> None:  # a network whose file is absent
        rows.append([num, *parts, "not shipped yet (RL)", *["-"] * (len(KPIS) - 1), paper_cell])

    for num, d, w, p, *paper in PAPER_TABLE3:
        policy = TABLE3_POLICIES[num]
        paper_text = " / ".join(paper)
        if policy in LEARNED and policy not in learned_names():
            not_shipped(num, (d, w, p), paper_text)
        else:
            run(num, policy, (d, w, p), paper_text, paper_text)
    if solver_rows:
        for num, policy in SOLVER_ROWS:
            run(num, policy, SOLVER_PARTS[policy], "", "(not in the paper)")
    if tuned_rows:
        for num, policy in TUNED_ROWS:
            run(num, policy, TUNED_PARTS[policy], "", "(beyond the paper: tuned on public seeds)")
    if learned_rows:
        for num, policy in LEARNED_ROWS:
            cell = "(beyond the paper: trained on paper-64)"
            if policy in learned_names():
                run(num, policy, LEARNED_PARTS[policy], "", cell)
            else:
                not_shipped(num, LEARNED_PARTS[policy], cell)
    if oracle_rows:
        for num, policy in ORACLE_ROWS:
            run(num, policy, ORACLE_PARTS[policy], "", "(not in the paper; reads the future)")
        from wfbench.core.bound import score_upper_bound

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
        "public seeds 1000-1049 (wfbench tune, docs/policies.md); L1-L3 (beyond the paper) are the other shipped "
        "networks: independent agents, hindsight learning, and ppo-joint with its workforce head improved by "
        "hindsight learning (docs/hindsight-learning.md); "
        "O1-O2 are hindsight oracles (they read the episode's future: not deployable) and B is a proven upper "
        "bound on NSW per seed (docs/hindsight.md).",
        "", markdown_table(header, rows), "", DIRECTION,
    ])
    return Output(md, _write(out, "table3", md, pd.DataFrame(records)))


# the methods of Figure 3, in groups drawn side by side; the paper's figure has the first group and PPO. The
# learned group holds every network of the registry (policies.registry.LEARNED), drawn where it is shipped
FIGURE3_GROUPS = (
    ("Paper rows 1-4", ("random", "random-dispatch", "random-positioning", "heuristic")),
    ("Solvers and tuned", ("solver", "heuristic-tuned", "solver-tuned")),
    ("Learned (RL)", ("ppo-dispatch", "ppo-joint", *[n for n in LEARNED if n not in ("ppo-dispatch", "ppo-joint")])),
    ("Hindsight oracles (read the future)", ("oracle-dispatch", "oracle")),
)
FIGURE3_METHODS = tuple(m for _, ms in FIGURE3_GROUPS for m in ms)
FIGURE3_REFERENCE = "heuristic"  # drawn dashed in every group, for comparison
FIGURE3_COLORS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3", "#8c8c8c")


def figure3_methods() -> tuple[str, ...]:
    """The methods Figure 3 draws here: all of :data:`FIGURE3_METHODS` but the learned ones not available.

    A learned policy (``policies.registry.LEARNED``) needs its shipped checkpoint and torch.
    """
    import importlib.util

    have_torch = importlib.util.find_spec("torch") is not None
    available = set(learned_names()) if have_torch else set()
    return tuple(m for m in FIGURE3_METHODS if m not in LEARNED or m in available)


def figure3(out: Path, runs: int = 50, backend: str = "process", workers: int | None = None,
            address: str | None = None, progress: Progress = None,
            methods: tuple[str, ...] | None = None) -> Output:
    """Per-step KPI bands over the episode: the paper's methods beside the solver, tuned, RL and oracle ones.

    One column per group of :data:`FIGURE3_GROUPS` (a method outside them gets a group of
    its own), one row per KPI (workforce cost, utilization, downtime); each method of a
    group is its per-step median and 25th-75th percentile band over ``runs`` episodes of
    paper-64, and the heuristic is drawn dashed in every group. ``methods`` defaults to
    :func:`figure3_methods` (the learned ones only where their checkpoint and torch are).
    Writes figure3.png, figure3.svg, figure3.md and figure3.csv (the bands every 10 steps).
    """
    from wfbench.core.config import ScenarioConfig
    from wfbench.core.state import METRICS
    from wfbench.plots import new_figure, save_figure, utilization_band

    methods = figure3_methods() if methods is None else tuple(methods)
    grouped = [(title, tuple(m for m in ms if m in methods)) for title, ms in FIGURE3_GROUPS]
    grouped = [(t, ms) for t, ms in grouped if ms]
    known = {m for _, ms in FIGURE3_GROUPS for m in ms}
    grouped += [("Other", tuple(m for m in methods if m not in known))] if set(methods) - known else []
    seeds = list(range(runs))
    rows_kpi = ("workforce_cost", "utilization", "downtime")
    fig = new_figure(figsize=(4.4 * len(grouped), 8.2), layout="constrained")
    axes = fig.subplots(3, len(grouped), sharex=True, sharey="row", squeeze=False)
    records = []
    bands: dict[str, list[np.ndarray]] = {}
    for m in dict.fromkeys([*methods, *([FIGURE3_REFERENCE] if len(grouped) > 1 else [])]):
        if progress:
            progress(m)
        _, series = evaluate(m, "paper-64", seeds, backend=backend, workers=workers, address=address,
                             return_series=True)
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
            if k == "utilization":
                ax.axhspan(*utilization_band(ScenarioConfig.resolve("paper-64")), color="0.9", zorder=0)
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
            if i == 2:
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
    files = _write(out, "figure3", md, pd.DataFrame(records))
    return Output(md, [png, svg, *files])


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

    from wfbench.core.bound import score_upper_bound
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
