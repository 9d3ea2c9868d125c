"""The ranking of a suite track (``suite-v1``): the aggregate over scenarios, per split.

Each stored row is one (scenario, seed) episode. Its NSW is normalized per scenario
(:func:`wfbench.suites.normalize`: 0 the random policy, 1 the proven bound), and an
entry's scores are aggregated per split by :func:`wfbench.aggregate.aggregate_suite`
(rliable: IQM, mean and optimality gap with 95% stratified bootstrap intervals over the
seeds within each scenario). Entries are ranked by the IQM over the held-out scenarios,
which nobody trained or tuned on; the training scenarios' aggregate is shown beside it.
Each entry's interval is computed with the same fixed seed and alone, so it does not
change when other entries are added. Costs and the budget filter are those of
:mod:`leaderboard.report`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from leaderboard.report import (
    BUDGET_HEADER,
    FORMATS,
    REFERENCE_TITLE,
    Ranking,
    add_budget,
    budget_cells,
    budget_note,
    entry_record,
    page,
    png_data,
)
from leaderboard.store import Store
from leaderboard.tracks import SuiteTrack
from wfbench.aggregate import METRICS, aggregate_suite
from wfbench.suites import normalize
from wfbench.tables import markdown_table, text_table

RANK_SPLIT = "heldout"  # the split the ranking reads; the training split is shown beside it
SPLIT_LABELS = {"heldout": "Held-out", "train": "Training"}
REPS = 2000  # bootstrap replications per entry and split (rliable's IQM costs about 0.6 ms each on 50 x 8 scores)
SEED = 0  # the bootstrap's seed: the same rows give the same intervals to the last digit


def normalized_rows(rows: pd.DataFrame, track: SuiteTrack) -> tuple[pd.DataFrame, list[str]]:
    """``rows`` with ``split`` and ``normalized`` columns, and a message per scenario that cannot be normalized."""
    split_of = {sc.id: sc.split for sc in track.suite.scenarios}
    out = rows.assign(split=rows["scenario"].map(split_of), normalized=np.nan)
    problems = []
    for scenario, idx in out.groupby("scenario").groups.items():
        try:
            out.loc[idx, "normalized"] = normalize(out.loc[idx, "nsw"].to_numpy(), str(scenario), track.suite)
        except ValueError as exc:  # no reference constants for this scenario's definition
            problems.append(f"scenario {scenario}: {exc}")
    return out, problems


def ranking(store: Store, track: SuiteTrack, baseline: str = "heuristic", max_decision_ms: float | None = None,
            max_cpu_s: float | None = None, reps: int = REPS) -> Ranking:
    """Rank the complete entries of a suite track by the IQM of their normalized score over the held-out scenarios.

    An entry is ranked when it is deployable, complete (a valid row for every scenario
    and test seed) and within the budget, if one is given. Every complete entry is
    aggregated (the oracles too, in their own section); incomplete and failed ones are
    listed after the ranked ones with their status. ``baseline`` is the entry the
    probability of improvement is taken over, when it is complete.

    Returns:
        The ranking: its table has per entry ``iqm_heldout`` (with ``_low`` and ``_high``),
        ``mean_heldout``, ``optimality_gap_heldout``, the same for ``train``,
        ``p_improve_heldout`` over the baseline, the raw mean ``nsw``, and the costs.
    """
    rows, refused = store.results(track)
    rows, problems = normalized_rows(rows, track)
    refused = refused + problems
    subs = {s.name: s for s in store.submissions(track.name)}
    n_units = len(track.units())
    out, left_out, frames = [], [], {}
    for name, sub in subs.items():
        mine = rows[rows["name"] == name]
        complete = sub.status == "complete" and len(mine) == n_units and mine["normalized"].notna().all()
        rec = entry_record(name, sub, mine)
        rec["nsw"] = float(mine["nsw"].mean()) if len(mine) else np.nan
        rec["ranked"] = rec["deployable"] and complete
        add_budget(rec, sub, mine, max_decision_ms, max_cpu_s, left_out)
        if complete:
            frames[name] = mine[["scenario", "split", "seed", "normalized"]]
        out.append(rec)
    table = pd.DataFrame(out)
    if frames:
        aggs = aggregate_suite(frames, baseline=baseline if baseline in frames else None, seed=SEED, reps=reps,
                               poi_reps=max(100, reps // 10), profile_reps=10)
        for split, agg in aggs.items():
            names = {}  # iqm -> iqm_heldout, iqm_low -> iqm_heldout_low, ...
            for base in (*METRICS, "p_improve"):
                for end in ("", "_low", "_high"):
                    if base + end in agg.table.columns:
                        names[base + end] = f"{base}_{split}{end}"
            table = table.join(agg.table.set_index("policy")[list(names)].rename(columns=names), on="name")
    if len(table):
        key = table.get(f"iqm_{RANK_SPLIT}", pd.Series(np.nan, index=table.index)).fillna(-np.inf)
        table = table.assign(_key=key).sort_values(["ranked", "_key"], ascending=[False, False]).drop(columns="_key")
        table["rank"] = [i + 1 if r else None for i, r in enumerate(table["ranked"])]
        table = table.reset_index(drop=True)
    limits = {k: v for k, v in (("max_decision_ms", max_decision_ms), ("max_cpu_s", max_cpu_s)) if v is not None}
    return Ranking(track, baseline, table, rows, refused, limits, left_out)  # type: ignore[arg-type]


def _interval(t: pd.Series, metric: str, split: str) -> str:
    v = t.get(f"{metric}_{split}", np.nan)
    if pd.isna(v):
        return "-"
    return f"{v:.3f} [{t[f'{metric}_{split}_low']:.3f}, {t[f'{metric}_{split}_high']:.3f}]"


def cells(r: Ranking, deployable: bool = True) -> tuple[list[str], list[list[str]]]:
    """Header and cells of the entries (deployable ones, or the oracles'), in rank order."""
    n = len(r.track.units())
    header = ["#", "Name", "Policy", "Held-out IQM [95% CI]", "Held-out mean [95% CI]",
              "Held-out optimality gap [95% CI]", "Training IQM [95% CI]",
              f"P(improvement over {r.baseline}), held out [95% CI]", "Episodes", "Status", *BUDGET_HEADER]
    rows = []
    for _, t in r.table.iterrows():
        if bool(t["deployable"]) != deployable:
            continue
        if t["name"] == r.baseline:
            poi = "(baseline)"
        else:
            poi = _interval(t, "p_improve", RANK_SPLIT).replace(".000", ".00")
        status = t["status"] + (f": {t['reason']}" if t["reason"] else "")
        if t["status"] == "complete" and t["seeds"] < n:
            status += f" ({n - t['seeds']} episodes missing or refused)"
        if t["over_budget"]:
            status += f"; outside the budget: {t['over_budget']}"
        rank = str(int(t["rank"])) if pd.notna(t["rank"]) else "-"
        rows.append([rank, t["name"], t["policy"], _interval(t, "iqm", RANK_SPLIT), _interval(t, "mean", RANK_SPLIT),
                     _interval(t, "optimality_gap", RANK_SPLIT), _interval(t, "iqm", "train"), poi,
                     f"{t['seeds']}/{n}", status, *budget_cells(t)])
    return header, rows


def scenario_cells(r: Ranking) -> tuple[list[str], list[list[str]]]:
    """Mean normalized score per scenario (rows, with their split) and entry (columns)."""
    names = r.table["name"].tolist() if len(r.table) else []
    header = ["Scenario", "Split", *names]
    means = r.per_seed.groupby(["scenario", "name"])["normalized"].mean() if len(r.per_seed) else pd.Series()
    rows = []
    for sc in r.track.suite.scenarios:
        rows.append([sc.id, sc.split, *[f"{means[sc.id, n]:.3f}" if (sc.id, n) in means.index else "-"
                                        for n in names]])
    return header, rows


def caption(r: Ranking) -> str:
    t = r.track
    seeds = t.test_seeds
    return (f"Track {t.name} (hash {t.hash}, the suite's): {t.description}; test seeds {seeds[0]}..{seeds[-1]} "
            f"({len(seeds)}) on each of {len(t.suite.scenarios)} scenarios. Ranked by the IQM of the normalized "
            "score over the held-out scenarios (0 = the random policy, 1 = the proven upper bound, per scenario; "
            "higher is better), with 95% stratified bootstrap intervals over seeds within scenarios (rliable); the "
            "training scenarios' IQM is shown beside it. Costs: wall ms per decision of one environment (median / "
            "worst 99th percentile over chunks), CPU s per episode, on the machine named" + budget_note(r) + ".")


def render(r: Ranking, fmt: str = "table") -> str:
    """The suite track's ranking as text, markdown, CSV or an HTML page."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; allowed: {', '.join(FORMATS)}")
    if fmt == "csv":
        return r.table.to_csv(index=False)
    header, rows = cells(r)
    _, ref = cells(r, deployable=False)
    if fmt == "html":
        return render_html(r, header, rows, ref)
    if not rows and not ref:
        return f"No submissions on track {r.track.name} yet: run 'wfbench leaderboard submit --track {r.track.name}'."
    table = markdown_table if fmt == "md" else text_table
    gap = "\n\n" if fmt == "md" else "\n"
    out = (table(header, rows) if rows else "No deployable submissions yet.") + gap + caption(r)
    if ref:
        out += f"\n\n{REFERENCE_TITLE}\n" + ("\n" if fmt == "md" else "") + table(header, ref)
    sh, sr = scenario_cells(r)
    out += "\n\nMean normalized score per scenario\n" + ("\n" if fmt == "md" else "") + table(sh, sr)
    return out


def iqm_figure(r: Ranking):
    """Bars of each aggregated entry's IQM per split with its 95% interval, or None when none is aggregated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    col = f"iqm_{RANK_SPLIT}"
    shown = r.table[r.table[col].notna()] if col in r.table else r.table.iloc[0:0]
    if shown.empty:
        return None
    names = shown["name"].tolist()
    fig, ax = plt.subplots(figsize=(max(5.0, 1.1 * len(names) + 2), 3.4))
    x = np.arange(len(names))
    for i, split in enumerate(("train", RANK_SPLIT)):
        if f"iqm_{split}" not in shown:
            continue
        mean = shown[f"iqm_{split}"].to_numpy()
        err = np.vstack([mean - shown[f"iqm_{split}_low"].to_numpy(), shown[f"iqm_{split}_high"].to_numpy() - mean])
        ax.bar(x + (i - 0.5) * 0.38, mean, 0.38, yerr=err, capsize=3, label=SPLIT_LABELS[split],
               color="#4c72b0" if split == RANK_SPLIT else "#a6bddb")
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.axhline(0.0, color="#888888", lw=0.8)
    ax.axhline(1.0, color="#888888", lw=0.8, ls="--")
    ax.set_ylabel("IQM of the normalized score")
    ax.set_title(f"{r.track.name}: 0 = random, 1 = the proven bound (dashed)", fontsize=10)
    ax.legend(fontsize=8, frameon=False)
    return fig


def render_html(r: Ranking, header: list[str], rows: list[list[str]], ref: list[list[str]]) -> str:
    """The self-contained page: the ranking, the oracles' section, the IQM chart and the per-scenario table."""
    import matplotlib.pyplot as plt

    fig = iqm_figure(r)
    figures = []
    if fig is not None:
        cap = "IQM of the normalized score per split with its 95% stratified bootstrap interval"
        figures.append((cap, png_data(fig)))
        plt.close(fig)
    sh, sr = scenario_cells(r)
    extra = [("Mean normalized score per scenario", "scenarios", sh, sr)]
    return page(r, caption(r), header, rows, ref, figures, extra)

