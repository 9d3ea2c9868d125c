"""The ranking of a suite track (``suite-v1``): the aggregate over scenarios, per split.

Each row's NSW is normalized per scenario (:func:`wfbench.scenarios.normalize`) and an entry's
scores are aggregated per split by :func:`wfbench.analysis.aggregate.aggregate_suite` (IQM, mean
and optimality gap with stratified bootstrap intervals, each entry alone with a fixed seed).
Entries rank by the held-out IQM; costs and the budget filter are those of
:mod:`wfbench.leaderboard.report`. A learned method entered once per training seed
(``METHOD#seedK``) is ranked as one pooled row ``METHOD (N seeds)``
(:func:`wfbench.analysis.aggregate.pool_seeds`), each seed in its own table (:func:`seed_cells`),
the shipped pick shown but not ranked. ``docs/leaderboard.md``, "The suite track".
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from wfbench.leaderboard.report import (
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
    reads_future,
)
from wfbench.leaderboard.tracks import SuiteTrack
from wfbench.policies.registry import parse_member, shipped_member

from wfbench.analysis.aggregate import STATISTICS, aggregate_suite, over_seeds, pool_seeds, seed_scores
from wfbench.analysis.tables import markdown_table, text_table
from wfbench.scenarios import normalize

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


def ranking(store: Any, track: SuiteTrack, baseline: str = "heuristic", max_decision_ms: float | None = None,
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
    groups: dict[str, list[tuple[int, str, bool]]] = {}  # method -> (training seed, entry, complete) per member
    for name, sub in subs.items():
        mine = rows[rows["name"] == name]
        complete = sub.status == "complete" and len(mine) == n_units and mine["normalized"].notna().all()
        rec = entry_record(name, sub, mine)
        rec["nsw"] = float(mine["nsw"].mean()) if len(mine) else np.nan
        rec["ranked"] = rec["deployable"] and complete
        method = _member_of(sub.policy)
        rec["member_of"], rec["pick_of"], rec["seeds_of"], rec["members"] = method[0] if method else "", "", "", ""
        if method:  # a training seed: ranked through its method's row
            rec["ranked"] = False
            groups.setdefault(method[0], []).append((method[1], name, complete))
        add_budget(rec, sub, mine, max_decision_ms, max_cpu_s, left_out)
        if complete and not method:
            frames[name] = mine[["scenario", "split", "seed", "normalized"]]
        out.append(rec)
    for rec in out:  # the shipped pick of a method whose seeds are entered: shown, named, not ranked twice
        if rec["policy"] in groups:
            rec["pick_of"], rec["ranked"] = rec["policy"], False
    for method, members in groups.items():
        rec, pooled = _method_record(method, sorted(members), subs, rows, max_decision_ms, max_cpu_s, left_out)
        if pooled is not None:
            frames[rec["name"]] = pooled
        out.append(rec)
    table = pd.DataFrame(out)
    if frames:
        aggs = aggregate_suite(frames, baseline=baseline if baseline in frames else None, seed=SEED, reps=reps,
                               poi_reps=max(100, reps // 10), profile_reps=10)
        for split, agg in aggs.items():
            names = {}  # iqm -> iqm_heldout, iqm_low -> iqm_heldout_low, ...
            for base in (*STATISTICS, "p_improve"):
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


def _member_of(policy: str) -> tuple[str, int] | None:
    """A training seed's policy ``METHOD#seedK[@MODE]`` -> (``METHOD[@MODE]``, K); None for any other policy."""
    parsed = parse_member(policy)
    if parsed is None or parsed[1] < 0:
        return None
    method, k, mode = parsed
    return method + (f"@{mode}" if mode else ""), k


def _method_record(method: str, members: list[tuple[int, str, bool]], subs: dict, rows: pd.DataFrame,
                   max_decision_ms: float | None, max_cpu_s: float | None,
                   left_out: list[str]) -> tuple[dict, pd.DataFrame | None]:
    """The row of a learned method over its entered training seeds, and its pooled runs when every seed is complete."""
    names = [name for _, name, _ in members]
    mine = rows[rows["name"].isin(names)]
    first = subs[names[0]]
    rec = entry_record(over_seeds(method, len(members)), first, mine)
    missing = [name for _, name, complete in members if not complete]
    rec.update(policy=f"{method} over training seeds " + ", ".join(str(k) for k, _, _ in members),
               submitter=", ".join(dict.fromkeys(subs[n].submitter for n in names)),
               status="complete" if not missing else "incomplete",
               reason=f"training seeds not complete: {', '.join(missing)}" if missing else "",
               builtin=False, fingerprint=",".join(subs[n].fingerprint or "legacy" for n in names),
               deployable=all(not reads_future(subs[n].policy) for n in names), nsw=float(mine["nsw"].mean())
               if len(mine) else np.nan, member_of="", pick_of="", seeds_of=method, members=",".join(names))
    rec["ranked"] = rec["deployable"] and not missing
    add_budget(rec, first, mine, max_decision_ms, max_cpu_s, left_out)
    if missing:
        return rec, None
    cols = ["scenario", "split", "seed", "normalized"]
    return rec, pool_seeds({n: rows.loc[rows["name"] == n, cols] for n in names})


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
        if bool(t["deployable"]) != deployable or t.get("member_of"):  # a training seed: in seed_cells
            continue
        if t["name"] == r.baseline:
            poi = "(baseline)"
        else:
            poi = _interval(t, "p_improve", RANK_SPLIT).replace(".000", ".00")
        status = t["status"] + (f": {t['reason']}" if t["reason"] else "")
        total = n * len(t["members"].split(",")) if t.get("members") else n  # a method: every seed's episodes
        if t["status"] == "complete" and t["seeds"] < total:
            status += f" ({total - t['seeds']} episodes missing or refused)"
        if t["over_budget"]:
            status += f"; outside the budget: {t['over_budget']}"
        if t.get("pick_of"):
            status += f"; the shipped pick of {t['pick_of']}, ranked over its training seeds"
        rank = str(int(t["rank"])) if pd.notna(t["rank"]) else "-"
        rows.append([rank, t["name"], t["policy"], _interval(t, "iqm", RANK_SPLIT), _interval(t, "mean", RANK_SPLIT),
                     _interval(t, "optimality_gap", RANK_SPLIT), _interval(t, "iqm", "train"), poi,
                     f"{t['seeds']}/{total}", status, *budget_cells(t)])
    return header, rows


def scenario_cells(r: Ranking) -> tuple[list[str], list[list[str]]]:
    """Mean normalized score per scenario (rows, with their split) and entry (columns); training seeds in seed_cells."""
    shown = r.table[~_is_member(r.table)] if len(r.table) else r.table
    names = shown["name"].tolist() if len(shown) else []
    header = ["Scenario", "Split", *names]
    rows_of = {t["name"]: t["members"].split(",") if t.get("members") else [t["name"]] for _, t in shown.iterrows()}
    per = r.per_seed
    rows = []
    for sc in r.track.suite.scenarios:
        cells = []
        for n in names:
            g = per[(per["scenario"] == sc.id) & per["name"].isin(rows_of[n])] if len(per) else per
            cells.append(f"{g['normalized'].mean():.3f}" if len(g) else "-")
        rows.append([sc.id, sc.split, *cells])
    return header, rows


def _is_member(table: pd.DataFrame) -> pd.Series:
    if "member_of" not in table:
        return pd.Series(False, index=table.index)
    return table["member_of"].fillna("").astype(str) != ""


def seed_cells(r: Ranking) -> tuple[list[str], list[list[str]]]:
    """Each learned method's training seeds: IQM per split of each seed's normalized score, and its mean per scenario.

    One row per entered seed (the shipped pick marked), then the method's pooled row with its 95% intervals;
    empty when no method's seeds are entered.
    """
    splits = [RANK_SPLIT, "train"]
    ids = [sc.id for sc in r.track.suite.scenarios]
    header = ["Method", "Training seed (entry)", *(f"{SPLIT_LABELS[sp]} IQM" for sp in splits), "Status", *ids]
    if not len(r.table) or not _is_member(r.table).any():
        return header, []
    rows = []
    members = r.table[_is_member(r.table)]
    for method, g in members.groupby("member_of", sort=True):
        base = method.partition("@")[0]
        pick = shipped_member(base)
        complete = g[g["status"] == "complete"]["name"].tolist()
        per = r.per_seed[r.per_seed["name"].isin(complete)]
        scores = seed_scores({n: per[per["name"] == n] for n in complete if (per["name"] == n).any()}) \
            if len(per) else pd.DataFrame(columns=["member"])
        scores = scores.set_index("member") if len(scores) else scores
        for _, t in g.sort_values("policy").iterrows():
            name = t["name"]
            is_pick = pick is not None and t["policy"].partition("@")[0] == pick
            have = len(scores) and name in scores.index
            rows.append([method, name + (" (shipped pick)" if is_pick else ""),
                         *(f"{scores.loc[name, f'iqm_{sp}']:.3f}" if have and f"iqm_{sp}" in scores else "-"
                           for sp in splits),
                         t["status"] + (f": {t['reason']}" if t["reason"] else ""),
                         *(f"{scores.loc[name, sc]:.3f}" if have and sc in scores else "-" for sc in ids)])
        pooled = r.table[r.table["seeds_of"] == method]
        for _, t in pooled.iterrows():
            rank = f"#{int(t['rank'])}" if pd.notna(t["rank"]) else "not ranked"
            per_all = r.per_seed[r.per_seed["name"].isin(t["members"].split(","))]
            means = per_all.groupby("scenario")["normalized"].mean()
            rows.append([method, f"{t['name']}, pooled ({rank})", *(_interval(t, "iqm", sp) for sp in splits),
                         t["status"], *(f"{means[sc]:.3f}" if sc in means.index else "-" for sc in ids)])
    return header, rows


SEEDS_TITLE = ("Learned methods over training seeds: each seed's IQM and mean normalized score per scenario, the "
               "shipped pick (chosen on public seeds, before any test) marked; the method is ranked by the pooled row")


def caption(r: Ranking) -> str:
    t = r.track
    seeds = t.test_seeds
    return (f"Track {t.name} (hash {t.hash}, the suite's): {t.description}; test seeds {seeds[0]}..{seeds[-1]} "
            f"({len(seeds)}) on each of {len(t.suite.scenarios)} scenarios. Ranked by the IQM of the normalized "
            "score over the held-out scenarios (0 = the random policy, 1 = the proven upper bound, per scenario; "
            "higher is better), with 95% stratified bootstrap intervals over seeds within scenarios (rliable); the "
            "training scenarios' IQM is shown beside it. A learned method entered once per training seed is "
            "ranked by the aggregate over its seeds, 'METHOD (N seeds)'. Costs: wall ms per decision of one "
            "environment (median / worst 99th percentile over chunks), CPU s per episode, on the machine named"
            + budget_note(r) + ".")


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
    th, tr = seed_cells(r)
    if tr:
        out += f"\n\n{SEEDS_TITLE}\n" + ("\n" if fmt == "md" else "") + table(th, tr)
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
    th, tr = seed_cells(r)
    if tr:
        extra.append((SEEDS_TITLE, "seeds", th, tr))
    return page(r, caption(r), header, rows, ref, figures, extra)
