"""Rankings of a track: text, markdown, CSV and a self-contained HTML page."""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from leaderboard.store import KPI_COLUMNS, Store, scrub_paths
from leaderboard.tracks import Track
from policies import get
from wfbench.core.kpis import KPI_LABELS
from wfbench.evaluation import format_kpi, summarize
from wfbench.stats import bootstrap_ci, paired_difference
from wfbench.tables import markdown_table, text_table

FORMATS = ("table", "md", "csv", "html")


@dataclass
class Ranking:
    track: Track
    baseline: str
    table: pd.DataFrame  # one row per submission; ranked ones first
    per_seed: pd.DataFrame  # the valid stored rows
    refused: list[str] = field(default_factory=list)


def ranking(store: Store, track: Track, baseline: str = "heuristic") -> Ranking:
    """Rank the complete submissions of ``track`` by mean NSW over its test seeds.

    A submission is ranked when every test seed has a valid row and it is deployable.
    wfbench's hindsight oracles (``reads_trace``) read the episode's future: they are
    kept in a separate, unranked "not deployable" section as a reference. The paired
    difference to ``baseline`` is taken over the seeds both have; incomplete and failed
    submissions are listed after the ranked ones, with their status and reason. No
    absolute path of the submitter's machine reaches the table (policy specs and reasons
    show a file's name only, :func:`~leaderboard.store.scrub_paths`); an entry stored
    without a fingerprint (an older wfbench) has ``fingerprint`` ``"legacy"``.
    """
    rows, refused = store.results(track)
    subs = {s.name: s for s in store.submissions(track.name)}
    n_test = len(track.test_seeds)
    base = rows[rows["name"] == baseline].set_index("seed")["nsw"] if baseline in subs else pd.Series(dtype=float)
    out = []
    for name, sub in subs.items():
        mine = rows[rows["name"] == name]
        rec = {"name": name, "policy": scrub_paths(sub.policy), "submitter": sub.submitter, "status": sub.status,
               "reason": scrub_paths(sub.reason), "seeds": len(mine), "builtin": sub.builtin,
               "fingerprint": sub.fingerprint or "legacy"}
        rec["deployable"] = not reads_future(sub.policy)
        rec["ranked"] = rec["deployable"] and sub.status == "complete" and len(mine) == n_test
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
    return Ranking(track, baseline, table, rows, refused)


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
              f"NSW - {r.baseline} (paired, 95% CI)", "Seeds", "Status"]
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
        rank = str(int(t["rank"])) if pd.notna(t["rank"]) else "-"
        rows.append([rank, t["name"], t["policy"], *kpis, ci, diff, f"{t['seeds']}/{n}", status])
    return header, rows


def caption(r: Ranking) -> str:
    t = r.track
    return (f"Track {t.name} (hash {t.hash}): {t.description}; test seeds {t.test_seeds[0]}..{t.test_seeds[-1]} "
            f"({len(t.test_seeds)}). Ranked by mean NSW (higher is better); KPIs are mean (25%-75%) over seeds; "
            "intervals are bootstrap 95%; differences are paired by seed.")


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


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode()


def _figures(r: Ranking) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.plots import draw_kpi_distribution, utilization_band

    if r.table.empty:
        return []
    shown = r.table[r.table["seeds"] > 0]
    if shown.empty:
        return []
    names = shown["name"].tolist()
    figs = []
    fig = nsw_figure(r)
    figs.append(("Mean Nash social welfare with bootstrap 95% intervals, on its whole range [0, 1] (hatched: reads "
                 "the future, not deployable)", _png(fig)))
    plt.close(fig)
    low, high = band = utilization_band(r.track.config)
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.4))
    for ax, k in zip(axes, KPI_COLUMNS, strict=True):
        data = [r.per_seed.loc[r.per_seed["name"] == n, k].to_numpy() for n in names]
        draw_kpi_distribution(ax, data, names, k, band=band)
    fig.tight_layout()
    figs.append((f"Per-seed KPIs (boxes: 25%-75%, whiskers: 5%-95%, points: seeds; gray: the utilization band "
                 f"{low:.2f}-{high:.2f})", _png(fig)))
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
    from wfbench.plots import draw_paired_differences, new_figure

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
            "below, gray: contains zero)", _png(fig))


def render_html(r: Ranking) -> str:
    header, rows = _cells(r)
    _, ref = _cells(r, deployable=False)
    esc = html.escape

    def html_table(table_id: str, body: list[list[str]]) -> list[str]:
        out = [f"<table id='{table_id}'>",
               "<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead>", "<tbody>"]
        out += ["<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>" for row in body]
        return [*out, "</tbody></table>"]

    table = html_table("ranking", rows)
    if ref:
        table += [f"<h2>{esc(REFERENCE_TITLE)}</h2>", *html_table("reference", ref)]
    figures = "".join(f"<figure><img alt='{esc(cap)}' src='data:image/png;base64,{data}'>"
                      f"<figcaption>{esc(cap)}</figcaption></figure>" for cap, data in _figures(r))
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
<p>{esc(caption(r))}</p>
{"".join(table)}
{figures}
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
