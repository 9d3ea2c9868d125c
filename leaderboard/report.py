"""The one ranking of every track, and its text, markdown, CSV and self-contained HTML page.

A one-scenario track is a suite of one (:class:`~wfbench.leaderboard.tracks.Track`): every board
ranks by the IQM of the normalized score over the held-out scenarios, or over all scenarios where
none is held out (:attr:`Track.rank_split`), with stratified bootstrap intervals
(:func:`wfbench.analysis.aggregate.aggregate_suite`). Learned methods' training seeds pool into one
row; a table per scenario keeps each entry's KPIs, mean NSW and paired difference with intervals.
Costs sit beside scores, and a budget (``max_decision_ms``, ``max_cpu_s``) unranks what is over it.
``docs/leaderboard.md``, "How a board ranks: one rule for every track".
"""

from __future__ import annotations

import base64
import html
import io
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from wfbench.leaderboard.rows import KPI_COLUMNS, scrub_paths
from wfbench.leaderboard.tracks import Track
from wfbench.policies import get
from wfbench.policies.registry import parse_member, shipped_member

from wfbench.analysis.aggregate import STATISTICS, aggregate_suite, over_seeds, pool_seeds, seed_scores
from wfbench.analysis.stats import bootstrap_ci, paired_difference
from wfbench.analysis.tables import markdown_table, text_table
from wfbench.core.kpis import KPI_LABELS
from wfbench.harness.budget import budget_line
from wfbench.harness.evaluation import format_kpi, summarize

FORMATS = ("table", "md", "csv", "html")
SPLIT_LABELS = {"heldout": "held out", "train": "training", "all": "all scenarios"}
RANKED_OVER = {"heldout": "the held-out scenarios", "all": "all its scenarios"}  # the caption's words
REPS = 2000  # bootstrap replications per entry and split (docs/performance.md: about 0.2 s an entry on the VM)
SEED = 0  # the bootstrap's seed: the same rows give the same intervals to the last digit


@dataclass
class Ranking:
    track: Track
    baseline: str
    table: pd.DataFrame  # one row per entry (and per learned method over its seeds); ranked ones first
    per_seed: pd.DataFrame  # the valid stored rows, with split, scenario_id and normalized columns
    refused: list[str] = field(default_factory=list)
    budget: dict[str, float] = field(default_factory=dict)  # the limits asked for: max_decision_ms, max_cpu_s
    left_out: list[str] = field(default_factory=list)  # one line per complete entry the budget left unranked
    scenarios: pd.DataFrame = field(default_factory=pd.DataFrame)  # one row per (scenario, shown entry)


def entry_budget(mine: pd.DataFrame) -> dict[str, float | str]:
    """An entry's measured cost from its rows (stored before budgets: NaN and ``""``).

    ``decision_ms_p50`` is the median of its chunks' medians, ``decision_ms_p99`` the
    largest of its chunks' 99th percentiles (the budget filter reads it), ``cpu_s`` the
    mean CPU seconds per episode, ``machine`` the machine its rows ran on (the most
    frequent one, and how many others there were).
    """
    if "machine" not in mine or mine["machine"].isna().all():
        return {"decision_ms_p50": np.nan, "decision_ms_p99": np.nan, "cpu_s": np.nan, "machine": ""}
    machines = mine["machine"].dropna().value_counts()
    where = str(machines.index[0]) + (f" (+{len(machines) - 1} other)" if len(machines) > 1 else "")

    def stat(column: str, how: str) -> float:
        values = mine[column].dropna()
        return float(getattr(values, how)()) if len(values) else np.nan

    return {"decision_ms_p50": stat("decision_ms_p50", "median"), "decision_ms_p99": stat("decision_ms_p99", "max"),
            "cpu_s": stat("cpu_s", "mean"), "machine": where}


def over_budget(rec: dict, max_decision_ms: float | None, max_cpu_s: float | None) -> str:
    """Why an entry is outside the budget (``""`` when it is within it, or no budget is asked)."""
    why = []
    if max_decision_ms is not None:
        p99 = rec.get("decision_ms_p99", np.nan)
        if not np.isfinite(p99):
            why.append("no decision time recorded")
        elif p99 > max_decision_ms:
            why.append(f"p99 {p99:.3g} ms per decision > {max_decision_ms:g} ms")
    if max_cpu_s is not None:
        cpu = rec.get("cpu_s", np.nan)
        if not np.isfinite(cpu):
            why.append("no CPU time recorded")
        elif cpu > max_cpu_s:
            why.append(f"{cpu:.3g} CPU s per episode > {max_cpu_s:g} s")
    return "; ".join(dict.fromkeys(why))


def entry_record(name: str, sub, mine: pd.DataFrame) -> dict:
    """What every board shows of a submission: who, what (paths scrubbed), its status and whether it may rank."""
    return {"name": name, "policy": scrub_paths(sub.entry), "submitter": sub.account, "status": sub.status,
            "reason": scrub_paths(sub.reason), "seeds": len(mine), "builtin": sub.builtin,
            "fingerprint": sub.fingerprint or "legacy", "deployable": not reads_future(sub.entry)}


def add_budget(rec: dict, sub, mine: pd.DataFrame, max_decision_ms: float | None, max_cpu_s: float | None,
               left_out: list[str]) -> None:
    """Put the entry's costs on ``rec`` and unrank it (saying why in ``left_out``) when it is over the budget."""
    rec.update(entry_budget(mine))
    rec["cost"] = scrub_paths(budget_line(json.loads(sub.budget))) if sub.budget else "not recorded"
    rec["over_budget"] = over_budget(rec, max_decision_ms, max_cpu_s)
    if rec["ranked"] and rec["over_budget"]:
        rec["ranked"] = False
        left_out.append(f"{rec['name']}: {rec['over_budget']}")


def normalized_rows(rows: pd.DataFrame, track: Track) -> tuple[pd.DataFrame, list[str]]:
    """``rows`` with ``scenario_id``, ``split`` and ``normalized`` columns; a message per scenario not normalized."""
    of = dict(track.scenarios())
    out = rows.assign(scenario_id=rows["scenario"].map(lambda k: of[k].id),
                      split=rows["scenario"].map(lambda k: of[k].split), normalized=np.nan)
    problems = []
    for key, idx in out.groupby("scenario").groups.items():
        try:
            out.loc[idx, "normalized"] = track.normalized(str(key), out.loc[idx, "nsw"].to_numpy())
        except ValueError as exc:  # no reference constants for this scenario's definition
            problems.append(f"scenario {of[str(key)].id}: {exc}; its rows are shown, not ranked")
    return out, problems


def ranking(board: Any, track: Track, baseline: str = "heuristic", max_decision_ms: float | None = None,
            max_cpu_s: float | None = None, reps: int = REPS, phase: str = "test") -> Ranking:
    """Rank the complete entries of ``track`` by the IQM of their normalized score over its rank split.

    ``board`` is read through its ``entries(track, phase)`` and ``results(track, phase)``: a
    :class:`~wfbench.leaderboard.board.db.Board` (a hosted board's ``phase``, ranked with
    :meth:`~wfbench.leaderboard.board.db.Board.phase_track`), the local board
    (:class:`~wfbench.leaderboard.store.Store`, whose entries are of the test phase) or a
    read-only :class:`~wfbench.leaderboard.schema4.Schema4Store`.

    The rank split is the held-out scenarios, or all of them where none is held out
    (:attr:`~wfbench.leaderboard.tracks.Track.rank_split`). An entry is ranked when it is
    deployable (wfbench's hindsight oracles read the future: their own unranked section),
    complete (a valid, normalized row for every scenario and test seed) and within the budget,
    if one is given: ``max_decision_ms`` is read against the entry's p99 milliseconds per
    decision, ``max_cpu_s`` against its CPU seconds per episode; :attr:`Ranking.left_out`
    names the entries over it. A learned method entered once per training seed
    (``METHOD#seedK``) is ranked as one row ``METHOD (N seeds)`` over the pool of its runs.
    ``baseline`` is the entry the probability of improvement and the paired NSW differences
    are taken over. No absolute path of a submitter's machine reaches the table
    (:func:`~wfbench.leaderboard.rows.scrub_paths`); an entry stored without a fingerprint
    has ``fingerprint`` ``"legacy"``.

    Returns:
        The ranking: its table has per entry ``iqm_<split>`` (with ``_low`` and ``_high``),
        ``mean_<split>`` and ``optimality_gap_<split>`` for each split present and the rank
        split, ``p_improve_<split>`` over the baseline, the KPIs over its rows (mean, ``_q25``,
        ``_q75``), ``nsw_ci_low``/``_high``, the paired ``diff`` to the baseline, and the costs.
    """
    rows, refused = board.results(track, phase)
    rows, problems = normalized_rows(rows, track)
    refused = refused + problems
    subs = {s.name: s for s in board.entries(track.name, phase)}
    n_units = len(track.units())
    out, left_out, frames = [], [], {}
    groups: dict[str, list[tuple[int, str, bool]]] = {}  # method -> (training seed, entry, complete) per member
    for name, sub in subs.items():
        mine = rows[rows["name"] == name]
        complete = sub.status == "complete" and len(mine) == n_units and mine["normalized"].notna().all()
        rec = entry_record(name, sub, mine)
        rec["ranked"] = rec["deployable"] and complete
        method = _member_of(sub.entry)
        rec["member_of"], rec["pick_of"], rec["seeds_of"], rec["members"] = method[0] if method else "", "", "", ""
        if method:  # a training seed: ranked through its method's row
            rec["ranked"] = False
            groups.setdefault(method[0], []).append((method[1], name, complete))
        add_budget(rec, sub, mine, max_decision_ms, max_cpu_s, left_out)
        if complete and not method:
            frames[name] = _frame(mine)
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
        table = _join_aggregates(table, frames, track, baseline, reps)
    members_of = _members_of(table)
    if len(table):
        table = table.join(_entry_stats(rows, baseline, members_of), on="name")
        key = table.get(f"iqm_{track.rank_split}", pd.Series(np.nan, index=table.index)).fillna(-np.inf)
        table = table.assign(_key=key).sort_values(["ranked", "_key"], ascending=[False, False]).drop(columns="_key")
        table["rank"] = [i + 1 if r else None for i, r in enumerate(table["ranked"])]
        table = table.reset_index(drop=True)
    scenarios = _scenario_stats(rows, table, track, baseline, members_of)
    limits = {k: v for k, v in (("max_decision_ms", max_decision_ms), ("max_cpu_s", max_cpu_s)) if v is not None}
    return Ranking(track, baseline, table, rows, refused, limits, left_out, scenarios)


def _frame(mine: pd.DataFrame) -> pd.DataFrame:
    """An entry's rows as the aggregate reads them: scenario (its id), split, seed, normalized."""
    return mine[["scenario_id", "split", "seed", "normalized"]].rename(columns={"scenario_id": "scenario"})


def _join_aggregates(table: pd.DataFrame, frames: dict[str, pd.DataFrame], track: Track, baseline: str,
                     reps: int) -> pd.DataFrame:
    """``table`` with each aggregated entry's statistics per split, and over the rank split."""
    aggs = aggregate_suite(frames, baseline=baseline if baseline in frames else None, seed=SEED, reps=reps,
                           poi_reps=max(100, reps // 10), profile_reps=10)
    if track.rank_split == "all":  # no held-out scenario: every scenario is a training one, and "all" is that one
        aggs["all"] = aggs["train"]
    for split, agg in aggs.items():
        names = {}  # iqm -> iqm_heldout, iqm_low -> iqm_heldout_low, ...
        for base in (*STATISTICS, "p_improve"):
            for end in ("", "_low", "_high"):
                if base + end in agg.table.columns:
                    names[base + end] = f"{base}_{split}{end}"
        table = table.join(agg.table.set_index("policy")[list(names)].rename(columns=names), on="name")
    return table


def _members_of(table: pd.DataFrame) -> dict[str, list[str]]:
    """The entries whose rows each shown row stands for: its own, or a method's training seeds."""
    if not len(table):
        return {}
    return {t["name"]: t["members"].split(",") if t.get("members") else [t["name"]] for _, t in table.iterrows()}


def _stats(mine: pd.DataFrame, base: pd.Series) -> dict[str, float]:
    """KPIs (mean, 25% and 75%), the mean NSW's interval and the paired NSW difference to ``base``.

    Pairs are (scenario, seed) units; a learned method's training seeds are averaged per unit first.
    """
    rec: dict[str, float] = {}
    for k, (mean, q25, q75) in summarize(mine, KPI_COLUMNS).items():
        rec[k], rec[f"{k}_q25"], rec[f"{k}_q75"] = mean, q25, q75
    ci = bootstrap_ci(mine["nsw"].to_numpy())
    rec["nsw_ci_low"], rec["nsw_ci_high"] = ci.low, ci.high
    a, b = mine.groupby(["scenario", "seed"])["nsw"].mean().align(base, join="inner")
    if len(a):
        rec["diff"], rec["diff_low"], rec["diff_high"] = paired_difference(a.to_numpy(), b.to_numpy())
        rec["common_seeds"] = len(a)
    return rec


def _baseline_units(rows: pd.DataFrame, baseline: str, members_of: dict[str, list[str]]) -> pd.Series:
    mine = rows[rows["name"].isin(members_of.get(baseline, []))]
    return mine.groupby(["scenario", "seed"])["nsw"].mean()


def _entry_stats(rows: pd.DataFrame, baseline: str, members_of: dict[str, list[str]]) -> pd.DataFrame:
    """Per shown row with rows, :func:`_stats` over all its rows, indexed by name."""
    base = _baseline_units(rows, baseline, members_of)
    out = {}
    for name, names in members_of.items():
        mine = rows[rows["name"].isin(names)]
        if len(mine):
            out[name] = _stats(mine, base.iloc[0:0] if name == baseline else base)
    return pd.DataFrame.from_dict(out, orient="index", columns=_stats_columns()) if out else \
        pd.DataFrame(columns=_stats_columns())


def _stats_columns() -> list[str]:
    kpis = [c for k in KPI_COLUMNS for c in (k, f"{k}_q25", f"{k}_q75")]
    return [*kpis, "nsw_ci_low", "nsw_ci_high", "diff", "diff_low", "diff_high", "common_seeds"]


def _scenario_stats(rows: pd.DataFrame, table: pd.DataFrame, track: Track, baseline: str,
                    members_of: dict[str, list[str]]) -> pd.DataFrame:
    """One row per (scenario, shown entry with rows there), in rank order: its normalized mean and :func:`_stats`."""
    shown = table.loc[~_is_member(table), "name"].tolist() if len(table) else []
    base = _baseline_units(rows, baseline, members_of)
    out = []
    for key, sc in track.scenarios():
        here = rows[rows["scenario"] == key]
        for name in shown:
            mine = here[here["name"].isin(members_of[name])]
            if len(mine):
                out.append({"scenario": sc.id, "split": sc.split, "name": name, "seeds": len(mine),
                            "normalized": float(mine["normalized"].mean()),
                            **_stats(mine, base.iloc[0:0] if name == baseline else base)})
    return pd.DataFrame(out, columns=["scenario", "split", "name", "seeds", "normalized", *_stats_columns()])


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
               submitter=", ".join(dict.fromkeys(subs[n].account for n in names)),
               status="complete" if not missing else "incomplete",
               reason=f"training seeds not complete: {', '.join(missing)}" if missing else "",
               builtin=False, fingerprint=",".join(subs[n].fingerprint or "legacy" for n in names),
               deployable=all(not reads_future(subs[n].entry) for n in names), member_of="", pick_of="",
               seeds_of=method, members=",".join(names))
    rec["ranked"] = rec["deployable"] and not missing
    add_budget(rec, first, mine, max_decision_ms, max_cpu_s, left_out)
    if missing:
        return rec, None
    return rec, pool_seeds({n: _frame(rows[rows["name"] == n]) for n in names})


def _is_member(table: pd.DataFrame) -> pd.Series:
    if "member_of" not in table:
        return pd.Series(False, index=table.index)
    return table["member_of"].fillna("").astype(str) != ""


REFERENCE_TITLE = ("Not deployable (reads the future): hindsight oracles, a reference for what the deployable "
                   "policies leave on the table, not ranked (docs/hindsight.md)")


def reads_future(policy: str) -> bool:
    """Whether a stored entry's policy reads the episode's future (a hindsight oracle of wfbench's).

    Only registry names can: a ``module:attr`` submission that declares ``reads_trace``
    is refused at submission, and a report never imports a user's code.
    """
    if ":" in policy:
        return False
    try:
        return bool(getattr(get(policy), "reads_trace", False))
    except ValueError:  # a name this version no longer has
        return False


BUDGET_HEADER = ("ms per decision p50 / p99", "CPU s per episode", "Machine", "Training, tuning, solver limits")


def budget_cells(t: pd.Series) -> list[str]:
    """An entry's budget cells (:data:`BUDGET_HEADER`); ``-`` where nothing was measured."""
    p50, p99, cpu = t.get("decision_ms_p50", np.nan), t.get("decision_ms_p99", np.nan), t.get("cpu_s", np.nan)
    ms = f"{p50:.3g} / {p99:.3g}" if pd.notna(p50) and pd.notna(p99) else "-"
    return [ms, f"{cpu:.3g}" if pd.notna(cpu) else "-", t.get("machine") or "-", t.get("cost") or "-"]


def budget_note(r: Ranking) -> str:
    """``; ranked within ...`` for a ranking restricted to a budget, else ``""``."""
    parts = []
    if "max_decision_ms" in r.budget:
        parts.append(f"at most {r.budget['max_decision_ms']:g} ms per decision (p99)")
    if "max_cpu_s" in r.budget:
        parts.append(f"at most {r.budget['max_cpu_s']:g} CPU s per episode")
    if not parts:
        return ""
    left = f"; left out: {'; '.join(r.left_out)}" if r.left_out else "; none left out"
    return f"; ranked only within the budget of {' and '.join(parts)}{left}"


def check_format(fmt: str, what: str = "format") -> str:
    """``fmt`` if a board can be shown in it (:data:`FORMATS`), else ValueError; ``what``: as the message names it."""
    if fmt not in FORMATS:
        raise ValueError(f"{what} {fmt!r} is not allowed; allowed: {', '.join(FORMATS)}")
    return fmt


def png_data(fig) -> str:
    """A matplotlib figure as base64 PNG, for a data URI."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode()


def _interval(t: pd.Series, metric: str, split: str) -> str:
    v = t.get(f"{metric}_{split}", np.nan)
    if pd.isna(v):
        return "-"
    return f"{v:.3f} [{t[f'{metric}_{split}_low']:.3f}, {t[f'{metric}_{split}_high']:.3f}]"


def _status(t: pd.Series) -> str:
    return t["status"] + (" (legacy: no fingerprint)" if t["fingerprint"] == "legacy" else "") \
        + (f": {t['reason']}" if t["reason"] else "")


def cells(r: Ranking, deployable: bool = True) -> tuple[list[str], list[list[str]]]:
    """Header and cells of the entries (deployable ones, or the oracles'), in rank order."""
    n = len(r.track.units())
    split = r.track.rank_split
    over = SPLIT_LABELS[split]
    header = ["#", "Name", "Policy", f"IQM, {over} [95% CI]", f"Mean, {over} [95% CI]",
              f"Optimality gap, {over} [95% CI]", "IQM, training [95% CI]",
              f"P(improvement over {r.baseline}), {over} [95% CI]", "Episodes", "Status", *BUDGET_HEADER]
    rows = []
    for _, t in r.table.iterrows():
        if bool(t["deployable"]) != deployable or t.get("member_of"):  # a training seed: in seed_cells
            continue
        poi = "(baseline)" if t["name"] == r.baseline else _interval(t, "p_improve", split).replace(".000", ".00")
        status = _status(t)
        total = n * len(t["members"].split(",")) if t.get("members") else n  # a method: every seed's episodes
        if t["status"] == "complete" and t["seeds"] < total:
            status += f" ({total - t['seeds']} episodes missing or refused)"
        if t["over_budget"]:
            status += f"; outside the budget: {t['over_budget']}"
        if t.get("pick_of"):
            status += f"; the shipped pick of {t['pick_of']}, ranked over its training seeds"
        rank = str(int(t["rank"])) if pd.notna(t["rank"]) else "-"
        rows.append([rank, t["name"], t["policy"], _interval(t, "iqm", split), _interval(t, "mean", split),
                     _interval(t, "optimality_gap", split), _interval(t, "iqm", "train"), poi,
                     f"{t['seeds']}/{total}", status, *budget_cells(t)])
    return header, rows


SCENARIOS_TITLE = ("Per scenario: the mean normalized score, the KPIs as mean (25%-75%) over seeds, the mean NSW's "
                   "bootstrap 95% interval and the NSW difference to the baseline, paired by seed")


def scenario_cells(r: Ranking) -> tuple[list[str], list[list[str]]]:
    """One row per scenario and shown entry (rank order), training seeds pooled into their method's row."""
    n = len(r.track.test_seeds)
    header = ["Scenario", "Split", "Name", "Normalized mean", *[KPI_LABELS[k] for k in KPI_COLUMNS], "NSW 95% CI",
              f"NSW - {r.baseline} (paired, 95% CI)", "Seeds"]
    oracles = set(r.table.loc[~r.table["deployable"].astype(bool), "name"]) if len(r.table) else set()
    rows = []
    for _, s in r.scenarios.iterrows():
        if s["name"] == r.baseline:
            diff = "(baseline)"
        elif pd.notna(s["diff"]):
            diff = f"{s['diff']:+.4f} [{s['diff_low']:+.4f}, {s['diff_high']:+.4f}]"
            if s["common_seeds"] < n:
                diff += f" on {int(s['common_seeds'])} seeds"
        else:
            diff = "-"
        norm = f"{s['normalized']:.3f}" if pd.notna(s["normalized"]) else "-"
        rows.append([s["scenario"], s["split"], s["name"] + (" (reads the future)" if s["name"] in oracles else ""),
                     norm, *[format_kpi(s[k], s[f"{k}_q25"], s[f"{k}_q75"]) for k in KPI_COLUMNS],
                     f"[{s['nsw_ci_low']:.3f}, {s['nsw_ci_high']:.3f}]", diff, str(int(s["seeds"]))])
    return header, rows


def seed_cells(r: Ranking) -> tuple[list[str], list[list[str]]]:
    """Each learned method's training seeds: IQM per split of each seed's normalized score, and its mean per scenario.

    One row per entered seed (the shipped pick marked), then the method's pooled row with its 95% intervals;
    empty when no method's seeds are entered.
    """
    splits = list(dict.fromkeys([r.track.rank_split, "train"]))
    ids = [sc.id for sc in r.track.suite.scenarios]
    header = ["Method", "Training seed (entry)", *(f"IQM, {SPLIT_LABELS[sp]}" for sp in splits), "Status", *ids]
    if not len(r.table) or not _is_member(r.table).any():
        return header, []
    rows = []
    members = r.table[_is_member(r.table)]
    for method, g in members.groupby("member_of", sort=True):
        pick = shipped_member(method.partition("@")[0])
        complete = [n for n in g.loc[g["status"] == "complete", "name"] if (r.per_seed["name"] == n).any()]
        frames = {n: _frame(r.per_seed[r.per_seed["name"] == n]) for n in complete}
        scores = pd.DataFrame(columns=["member"])
        if frames:
            scores = seed_scores(frames).merge(
                seed_scores({n: f.assign(split="all") for n, f in frames.items()})[["member", "iqm_all"]], on="member")
        scores = scores.set_index("member")
        for _, t in g.sort_values("policy").iterrows():
            name = t["name"]
            is_pick = pick is not None and t["policy"].partition("@")[0] == pick
            have = name in scores.index
            rows.append([method, name + (" (shipped pick)" if is_pick else ""),
                         *(f"{scores.loc[name, f'iqm_{sp}']:.3f}" if have and f"iqm_{sp}" in scores else "-"
                           for sp in splits), _status(t),
                         *(f"{scores.loc[name, sc]:.3f}" if have and sc in scores else "-" for sc in ids)])
        for _, t in r.table[r.table["seeds_of"] == method].iterrows():
            rank = f"#{int(t['rank'])}" if pd.notna(t["rank"]) else "not ranked"
            means = r.per_seed[r.per_seed["name"].isin(t["members"].split(","))].groupby("scenario_id")["normalized"]\
                .mean()
            rows.append([method, f"{t['name']}, pooled ({rank})", *(_interval(t, "iqm", sp) for sp in splits),
                         t["status"], *(f"{means[sc]:.3f}" if sc in means.index else "-" for sc in ids)])
    return header, rows


SEEDS_TITLE = ("Learned methods over training seeds: each seed's IQM and mean normalized score per scenario, the "
               "shipped pick (chosen on public seeds, before any test) marked; the method is ranked by the pooled row")


def caption(r: Ranking) -> str:
    t = r.track
    seeds = t.test_seeds
    n = len(t.suite.scenarios)
    where = "its one scenario" if n == 1 else f"each of {n} scenarios"
    return (f"Track {t.name} (hash {t.hash}): {t.description}; test seeds {seeds[0]}..{seeds[-1]} ({len(seeds)}) on "
            f"{where}. Ranked by the IQM of the normalized score over "
            f"{RANKED_OVER[t.rank_split]} (the held-out scenarios where a track has some, else all of them; "
            "0 = the random policy, 1 = the proven upper bound, per scenario; higher is better), with 95% "
            "stratified bootstrap intervals over seeds within scenarios (rliable). A learned method entered once "
            "per training seed is ranked by the aggregate over its seeds, 'METHOD (N seeds)'. Costs: wall ms per "
            "decision of one environment (median / worst 99th percentile over chunks; a compiled composite's CPU "
            "time per environment-step), CPU s per episode, on the machine named" + budget_note(r) + ".")


def render(r: Ranking, fmt: str = "table", per_seed: bool = True) -> str:
    """The ranking as text, markdown, CSV (one row per entry) or an HTML page (:func:`render_html`)."""
    check_format(fmt)
    if fmt == "csv":
        return r.table.to_csv(index=False)
    if fmt == "html":
        return render_html(r, per_seed)
    header, rows = cells(r)
    _, ref = cells(r, deployable=False)
    if not rows and not ref:
        return (f"No submissions on track {r.track.name} yet: run 'wfbench leaderboard baselines --track "
                f"{r.track.name}' or 'wfbench leaderboard submit --track {r.track.name}'.")
    table = markdown_table if fmt == "md" else text_table
    gap = "\n\n" if fmt == "md" else "\n"
    out = (table(header, rows) if rows else "No deployable submissions yet.") + gap + caption(r)
    for title, (h, body) in ((REFERENCE_TITLE, (header, ref)), (SCENARIOS_TITLE, scenario_cells(r)),
                             (SEEDS_TITLE, seed_cells(r))):
        if body:
            out += f"\n\n{title}\n" + ("\n" if fmt == "md" else "") + table(h, body)
    return out


DEPLOYABLE_COLOR = "#4c72b0"
ORACLE_COLOR = "#bbbbbb"
ORACLE_HATCH = "//"
ORACLE_LABEL = "reads the future, not deployable"


def iqm_figure(r: Ranking):
    """Bars of each aggregated entry's IQM per split with its 95% interval, or None when none is aggregated.

    The rank split's bars are dark, the training split's light (where it differs); an oracle's bars
    (it reads the future) are gray and hatched and the legend says it is not deployable.
    """
    from matplotlib.patches import Patch

    from wfbench.analysis.plots import new_figure

    rank = r.track.rank_split
    shown = r.table[r.table[f"iqm_{rank}"].notna()] if f"iqm_{rank}" in r.table else r.table.iloc[0:0]
    if shown.empty:
        return None
    names = shown["name"].tolist()
    oracle = ~shown["deployable"].to_numpy(dtype=bool)
    splits = [s for s in dict.fromkeys(("train", rank)) if f"iqm_{s}" in shown and (s == rank or rank != "all")]
    fig = new_figure(figsize=(max(5.0, 1.1 * len(names) + 2), 3.4))
    ax = fig.subplots()
    x, width = np.arange(len(names)), 0.76 / len(splits)
    for i, split in enumerate(splits):
        mean = shown[f"iqm_{split}"].to_numpy()
        err = np.vstack([mean - shown[f"iqm_{split}_low"].to_numpy(), shown[f"iqm_{split}_high"].to_numpy() - mean])
        color = DEPLOYABLE_COLOR if split == rank else "#a6bddb"
        bars = ax.bar(x + (i - (len(splits) - 1) / 2) * width, mean, width, yerr=err, capsize=3,
                      color=[ORACLE_COLOR if o else color for o in oracle], edgecolor=[
                          "#555555" if o else color for o in oracle])
        for bar, o in zip(bars, oracle, strict=True):
            if o:
                bar.set_hatch(ORACLE_HATCH)
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.axhline(0.0, color="#888888", lw=0.8)
    ax.axhline(1.0, color="#888888", lw=0.8, ls="--")
    ax.set_ylabel("IQM of the normalized score")
    ax.set_title(f"{r.track.name}: 0 = random, 1 = the proven bound (dashed)", fontsize=10)
    handles = [Patch(facecolor=DEPLOYABLE_COLOR if s == rank else "#a6bddb", label=SPLIT_LABELS[s]) for s in splits]
    if oracle.any():
        handles.append(Patch(facecolor=ORACLE_COLOR, edgecolor="#555555", hatch=ORACLE_HATCH, label=ORACLE_LABEL))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    return fig


def _scenario_figures(r: Ranking, per_seed: bool) -> list[tuple[str, str]]:
    """Per scenario: the per-seed KPIs (when ``per_seed``) and the paired NSW differences to the baseline."""
    from wfbench.analysis.plots import draw_kpi_distribution, draw_paired_differences, new_figure, utilization_band

    figs = []
    n = len(r.track.test_seeds)
    for key, sc in r.track.scenarios():
        stats = r.scenarios[r.scenarios["scenario"] == sc.id]
        if stats.empty:
            continue
        names = stats["name"].tolist()
        if per_seed:
            members = _members_of(r.table)
            here = r.per_seed[r.per_seed["scenario"] == key]
            low, high = band = utilization_band(sc.config)
            fig = new_figure(figsize=(16, 3.4), layout="constrained")
            for ax, k in zip(fig.subplots(1, 4), KPI_COLUMNS, strict=True):
                data = [here.loc[here["name"].isin(members[m]), k].to_numpy() for m in names]
                draw_kpi_distribution(ax, data, names, k, band=band)
            figs.append((f"{sc.id}: per-seed KPIs (boxes: 25%-75%, whiskers: 5%-95%, points: seeds; gray: the "
                         f"utilization band {low:.2f}-{high:.2f})", png_data(fig)))
        diffs = stats[stats["diff"].notna() & (stats["name"] != r.baseline)]
        if len(diffs):
            notes = [f"on {int(c)} seeds" if c < n else "" for c in diffs["common_seeds"]]
            fig = new_figure(figsize=(9, 1.2 + 0.45 * len(diffs)), layout="constrained")
            draw_paired_differences(fig.subplots(), diffs["name"].tolist(), diffs["diff"], diffs["diff_low"],
                                    diffs["diff_high"], r.baseline, notes)
            figs.append((f"{sc.id}: NSW minus {r.baseline}, paired by seed, with bootstrap 95% intervals (green: "
                         "above zero, red: below, gray: contains zero)", png_data(fig)))
    return figs


def render_html(r: Ranking, per_seed: bool = True) -> str:
    """The self-contained page: the ranking, the oracles' section, the IQM chart, the per-scenario figures and tables.

    ``per_seed=False`` leaves out the per-seed KPI figures (a hosted test phase shows only aggregates).
    """
    header, rows = cells(r)
    _, ref = cells(r, deployable=False)
    figures = []
    fig = iqm_figure(r)
    if fig is not None:
        figures.append(("IQM of the normalized score per split with its 95% stratified bootstrap interval (hatched: "
                        "reads the future, not deployable)", png_data(fig)))
    figures += _scenario_figures(r, per_seed)
    extra = [(SCENARIOS_TITLE, "scenarios", *scenario_cells(r))]
    th, tr = seed_cells(r)
    if tr:
        extra.append((SEEDS_TITLE, "seeds", th, tr))
    return page(r, caption(r), header, rows, ref, figures, extra)


def page(r: Ranking, text: str, header: list[str], rows: list[list[str]], ref: list[list[str]],
         figures: list[tuple[str, str]], extra: list[tuple[str, str, list[str], list[list[str]]]] = ()) -> str:
    """A self-contained HTML page of a ranking.

    Args:
        r: the ranking (its track's name and refused rows).
        text: the caption.
        header: the ranking table's header.
        rows: the deployable entries' cells.
        ref: the oracles' cells (their own section when there are any).
        figures: (caption, base64 PNG) pairs, embedded as data URIs.
        extra: more tables after the figures, as (title, HTML id, header, rows).
    """
    esc = html.escape

    def html_table(table_id: str, head: list[str], body: list[list[str]]) -> list[str]:
        out = [f"<table id='{table_id}'>",
               "<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr></thead>", "<tbody>"]
        out += ["<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>" for row in body]
        return [*out, "</tbody></table>"]

    table = html_table("ranking", header, rows)
    if ref:
        table += [f"<h2>{esc(REFERENCE_TITLE)}</h2>", *html_table("reference", header, ref)]
    shown = "".join(f"<figure><img alt='{esc(cap)}' src='data:image/png;base64,{data}'>"
                    f"<figcaption>{esc(cap)}</figcaption></figure>" for cap, data in figures)
    for title, table_id, head, body in extra:
        shown += f"<h2>{esc(title)}</h2>" + "".join(html_table(table_id, head, body))
    refused = ""
    if r.refused:
        refused = "<h2>Refused rows</h2><ul>" + "".join(f"<li>{esc(m)}</li>" for m in r.refused) + "</ul>"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>wfbench leaderboard: {esc(r.track.name)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; color: #222; }}
table {{ border-collapse: collapse; font-size: 0.9em; }}
th, td {{ border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: left; }}
th {{ background: #f0f0f0; }}
figure {{ margin: 1.5em 0; }} img {{ max-width: 100%; }}
</style></head>
<body>
<h1>wfbench leaderboard: {esc(r.track.name)}</h1>
<p>{esc(text)}</p>
{"".join(table)}
{shown}
{refused}
<script>
// lets a test (or a reader's console) confirm the embedded plots decoded
window.addEventListener("load", () => {{
  const ok = [...document.images].filter(i => i.complete && i.naturalWidth > 0).length;
  document.body.dataset.imagesDecoded = String(ok);
}});
</script>
</body></html>
"""
