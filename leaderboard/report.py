"""Rankings of a track: text, markdown, CSV and a self-contained HTML page.

Each entry shows what it cost beside what it scored: the milliseconds per decision
(p50, p99), the CPU seconds per episode, the machine it ran on, and what its policy
states about its own cost (training env-steps, wall time and hardware, tuning trials,
solver time limits). A ranking can be restricted to a budget (``max_decision_ms``,
``max_cpu_s``): entries over it, or with no measurement to compare, are listed unranked
with the reason.
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

from wfbench.analysis.stats import bootstrap_ci, paired_difference
from wfbench.analysis.tables import markdown_table, text_table
from wfbench.core.kpis import KPI_LABELS
from wfbench.harness.budget import budget_line
from wfbench.harness.evaluation import format_kpi, summarize

FORMATS = ("table", "md", "csv", "html")


@dataclass
class Ranking:
    track: Track
    baseline: str
    table: pd.DataFrame  # one row per submission; ranked ones first
    per_seed: pd.DataFrame  # the valid stored rows
    refused: list[str] = field(default_factory=list)
    budget: dict[str, float] = field(default_factory=dict)  # the limits asked for: max_decision_ms, max_cpu_s
    left_out: list[str] = field(default_factory=list)  # one line per complete entry the budget left unranked


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
    return {"name": name, "policy": scrub_paths(sub.policy), "submitter": sub.submitter, "status": sub.status,
            "reason": scrub_paths(sub.reason), "seeds": len(mine), "builtin": sub.builtin,
            "fingerprint": sub.fingerprint or "legacy", "deployable": not reads_future(sub.policy)}


def add_budget(rec: dict, sub, mine: pd.DataFrame, max_decision_ms: float | None, max_cpu_s: float | None,
               left_out: list[str]) -> None:
    """Put the entry's costs on ``rec`` and unrank it (saying why in ``left_out``) when it is over the budget."""
    rec.update(entry_budget(mine))
    rec["cost"] = scrub_paths(budget_line(json.loads(sub.budget))) if sub.budget else "not recorded"
    rec["over_budget"] = over_budget(rec, max_decision_ms, max_cpu_s)
    if rec["ranked"] and rec["over_budget"]:
        rec["ranked"] = False
        left_out.append(f"{rec['name']}: {rec['over_budget']}")


def ranking(store: Any, track: Track, baseline: str = "heuristic", max_decision_ms: float | None = None,
            max_cpu_s: float | None = None) -> Ranking:
    """Rank the complete submissions of ``track`` by mean NSW over its test seeds.

    With ``max_decision_ms`` (read against the entry's p99 milliseconds per decision)
    or ``max_cpu_s`` (CPU seconds per episode), only the entries within that budget are
    ranked; the others, and entries with no measurement (stored before budgets), stay
    listed, unranked, with the reason, and :attr:`Ranking.left_out` names them.

    A submission is ranked when every test seed has a valid row and it is deployable.
    wfbench's hindsight oracles (``reads_trace``) read the episode's future: they are
    kept in a separate, unranked "not deployable" section as a reference. The paired
    difference to ``baseline`` is taken over the seeds both have; incomplete and failed
    submissions are listed after the ranked ones, with their status and reason. No
    absolute path of the submitter's machine reaches the table (policy specs and reasons
    show a file's name only, :func:`~wfbench.leaderboard.rows.scrub_paths`); an entry stored
    without a fingerprint (an older wfbench) has ``fingerprint`` ``"legacy"``.
    """
    rows, refused = store.results(track)
    subs = {s.name: s for s in store.submissions(track.name)}
    n_test = len(track.test_seeds)
    base = rows[rows["name"] == baseline].set_index("seed")["nsw"] if baseline in subs else pd.Series(dtype=float)
    out = []
    left_out: list[str] = []
    for name, sub in subs.items():
        mine = rows[rows["name"] == name]
        rec = entry_record(name, sub, mine)
        rec["ranked"] = rec["deployable"] and sub.status == "complete" and len(mine) == n_test
        add_budget(rec, sub, mine, max_decision_ms, max_cpu_s, left_out)
        if len(mine):
            for k, (mean, q25, q75) in summarize(mine, KPI_COLUMNS).items():
                rec[k], rec[f"{k}_q25"], rec[f"{k}_q75"] = mean, q25, q75
            ci = bootstrap_ci(mine["nsw"].to_numpy())
            rec["nsw_ci_low"], rec["nsw_ci_high"] = ci.low, ci.high
            common = mine.set_index("seed")["nsw"].align(base, join="inner")
            if name != baseline and len(common[0]):
                d = paired_difference(common[0].to_numpy(), common[1].to_numpy())
                rec["diff"], rec["diff_low"], rec["diff_high"] = d
                rec["common_seeds"] = len(common[0])
        out.append(rec)
    table = pd.DataFrame(out)
    if len(table):
        table["_nsw"] = table.get("nsw", pd.Series(np.nan, index=table.index)).fillna(-np.inf)
        table = table.sort_values(["ranked", "_nsw"], ascending=[False, False]).drop(columns="_nsw")
        table["rank"] = [i + 1 if r else None for i, r in enumerate(table["ranked"])]
        table = table.reset_index(drop=True)
    limits = {k: v for k, v in (("max_decision_ms", max_decision_ms), ("max_cpu_s", max_cpu_s)) if v is not None}
    return Ranking(track, baseline, table, rows, refused, limits, left_out)


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


def _cells(r: Ranking, deployable: bool = True) -> tuple[list[str], list[list[str]]]:
    n = len(r.track.test_seeds)
    header = ["#", "Name", "Policy", *[KPI_LABELS[k] for k in KPI_COLUMNS], "NSW 95% CI",
              f"NSW - {r.baseline} (paired, 95% CI)", "Seeds", "Status", *BUDGET_HEADER]
    rows = []
    for _, t in r.table.iterrows():
        if bool(t["deployable"]) != deployable:
            continue
        has = t["seeds"] > 0
        kpis = [format_kpi(t[k], t[f"{k}_q25"], t[f"{k}_q75"]) if has else "-" for k in KPI_COLUMNS]
        ci = f"[{t['nsw_ci_low']:.3f}, {t['nsw_ci_high']:.3f}]" if has else "-"
        if t["name"] == r.baseline:
            diff = "(baseline)"
        elif has and pd.notna(t.get("diff", np.nan)):
            diff = f"{t['diff']:+.4f} [{t['diff_low']:+.4f}, {t['diff_high']:+.4f}]"
            if t.get("common_seeds", n) < n:
                diff += f" on {int(t['common_seeds'])} seeds"
        else:
            diff = "-"
        status = t["status"] + (" (legacy: no fingerprint)" if t["fingerprint"] == "legacy" else "") \
            + (f": {t['reason']}" if t["reason"] else "")
        if t["over_budget"]:
            status += f"; outside the budget: {t['over_budget']}"
        rank = str(int(t["rank"])) if pd.notna(t["rank"]) else "-"
        rows.append([rank, t["name"], t["policy"], *kpis, ci, diff, f"{t['seeds']}/{n}", status, *budget_cells(t)])
    return header, rows


BUDGET_HEADER = ("ms per decision p50 / p99", "CPU s per episode", "Machine", "Training, tuning, solver limits")


def budget_cells(t: pd.Series) -> list[str]:
    """An entry's budget cells (:data:`BUDGET_HEADER`); ``-`` where nothing was measured."""
    p50, p99, cpu = t.get("decision_ms_p50", np.nan), t.get("decision_ms_p99", np.nan), t.get("cpu_s", np.nan)
    ms = f"{p50:.3g} / {p99:.3g}" if pd.notna(p50) and pd.notna(p99) else "-"
    return [ms, f"{cpu:.3g}" if pd.notna(cpu) else "-", t.get("machine") or "-", t.get("cost") or "-"]


def caption(r: Ranking) -> str:
    t = r.track
    return (f"Track {t.name} (hash {t.hash}): {t.description}; test seeds {t.test_seeds[0]}..{t.test_seeds[-1]} "
            f"({len(t.test_seeds)}). Ranked by mean NSW (higher is better); KPIs are mean (25%-75%) over seeds; "
            "intervals are bootstrap 95%; differences are paired by seed. Costs: wall ms per decision of one "
            "environment (median / worst 99th percentile over chunks; a compiled composite's CPU time per "
            "environment-step), CPU s per episode, on the machine named" + budget_note(r) + ".")


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


def render(r: Ranking, fmt: str = "table") -> str:
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; allowed: {', '.join(FORMATS)}")
    if fmt == "csv":
        return r.table.to_csv(index=False)
    if fmt == "html":
        return render_html(r)
    header, rows = _cells(r)
    _, ref = _cells(r, deployable=False)
    if not rows and not ref:
        return f"No submissions on track {r.track.name} yet: run 'wfbench leaderboard seed' or 'submit'."
    table = markdown_table if fmt == "md" else text_table
    out = (table(header, rows) if rows else "No deployable submissions yet.") + ("\n\n" if fmt == "md" else "\n")
    out += caption(r)
    if ref:
        out += f"\n\n{REFERENCE_TITLE}\n" + ("\n" if fmt == "md" else "") + table(header, ref)
    return out


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


def _figures(r: Ranking) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.analysis.plots import draw_kpi_distribution, utilization_band

    if r.table.empty:
        return []
    shown = r.table[r.table["seeds"] > 0]
    if shown.empty:
        return []
    names = shown["name"].tolist()
    figs = []
    fig = nsw_figure(r)
    figs.append(("Mean Nash social welfare with bootstrap 95% intervals, on its whole range [0, 1] (hatched: reads "
                 "the future, not deployable)", png_data(fig)))
    plt.close(fig)
    low, high = band = utilization_band(r.track.config)
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.4))
    for ax, k in zip(axes, KPI_COLUMNS, strict=True):
        data = [r.per_seed.loc[r.per_seed["name"] == n, k].to_numpy() for n in names]
        draw_kpi_distribution(ax, data, names, k, band=band)
    fig.tight_layout()
    figs.append((f"Per-seed KPIs (boxes: 25%-75%, whiskers: 5%-95%, points: seeds; gray: the utilization band "
                 f"{low:.2f}-{high:.2f})", png_data(fig)))
    plt.close(fig)
    diffs = _paired_difference_figure(r, shown)
    return figs + ([diffs] if diffs else [])


DEPLOYABLE_COLOR = "#4c72b0"
ORACLE_COLOR = "#bbbbbb"
ORACLE_HATCH = "//"
ORACLE_LABEL = "reads the future, not deployable"


def nsw_figure(r: Ranking):
    """The bar chart of mean NSW with its 95% interval per entry that has rows, or None when none has.

    The axis is NSW's whole range, 0 to 1 (a welfare in [0, 1]): a cut axis would
    magnify the gaps. An oracle's bar (it reads the future) is gray and hatched and the
    legend says it is not deployable.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    shown = r.table[r.table["seeds"] > 0] if not r.table.empty else r.table
    if shown.empty:
        return None
    names = shown["name"].tolist()
    fig, ax = plt.subplots(figsize=(max(4.5, 0.8 * len(names) + 2), 3.4))
    mean = shown["nsw"].to_numpy()
    err = np.vstack([mean - shown["nsw_ci_low"].to_numpy(), shown["nsw_ci_high"].to_numpy() - mean])
    oracle = ~shown["deployable"].to_numpy(dtype=bool)
    bars = ax.bar(range(len(names)), mean, yerr=err, capsize=4,
                  color=[ORACLE_COLOR if o else DEPLOYABLE_COLOR for o in oracle],
                  edgecolor=["#555555" if o else DEPLOYABLE_COLOR for o in oracle])
    for bar, o in zip(bars, oracle, strict=True):
        if o:
            bar.set_hatch(ORACLE_HATCH)
    for i, m in enumerate(mean):
        ax.annotate(f"{m:.3f}", (i, 0.0), xytext=(0, 3), textcoords="offset points", ha="center", fontsize=8,
                    color="black" if oracle[i] else "white")
    ax.set_xticks(range(len(names)), names, rotation=30, ha="right")
    ax.set_ylabel("mean NSW (95% CI)")
    ax.set_ylim(0.0, 1.0)
    ax.set_title(f"Nash social welfare on {r.track.name} (axis: its whole range, 0 to 1)", fontsize=10)
    handles = [Patch(facecolor=DEPLOYABLE_COLOR, label="deployable")]
    if oracle.any():
        handles.append(Patch(facecolor=ORACLE_COLOR, edgecolor="#555555", hatch=ORACLE_HATCH, label=ORACLE_LABEL))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    return fig


def _paired_difference_figure(r: Ranking, shown: pd.DataFrame) -> tuple[str, str] | None:
    """The paired NSW differences to the baseline with their intervals, as in the table (none resampled here)."""
    from wfbench.analysis.plots import draw_paired_differences, new_figure

    if "diff" not in shown:
        return None
    rows = shown[shown["diff"].notna() & (shown["name"] != r.baseline)]
    if rows.empty:
        return None
    n = len(r.track.test_seeds)
    notes = [f"on {int(c)} seeds" if c < n else "" for c in rows["common_seeds"]]
    fig = new_figure(figsize=(9, 1.2 + 0.45 * len(rows)), layout="constrained")
    draw_paired_differences(fig.subplots(), rows["name"].tolist(), rows["diff"], rows["diff_low"],
                            rows["diff_high"], r.baseline, notes)
    return (f"NSW minus {r.baseline}, paired by seed, with bootstrap 95% intervals (green: above zero, red: "
            "below, gray: contains zero)", png_data(fig))


def render_html(r: Ranking) -> str:
    header, rows = _cells(r)
    _, ref = _cells(r, deployable=False)
    return page(r, caption(r), header, rows, ref, _figures(r))


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
