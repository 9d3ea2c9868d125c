"""The HTML pages of a hosted board: the home page, a track's board per phase, a submission, an error.

A board is the local leaderboard's own page (:mod:`wfbench.leaderboard.report`) over the hosted
rows (:meth:`Board.entries`, :meth:`Board.results`), so both boards rank, show costs and name oracles alike; a test
phase's rows carry seed indices and its page draws no per-seed figure: no page names a hidden
seed. Every text a submitter chose is escaped. A submission's page refreshes itself while it is queued or running.
``docs/leaderboard.md``, "The hosted leaderboard".
"""

from __future__ import annotations

import html
import threading
import weakref
from typing import Any

from wfbench.leaderboard import report
from wfbench.leaderboard.report import Ranking

from wfbench.core.kpis import KPI_LABELS

REFRESH_S = 3  # a queued or running submission's page reloads this often
esc = html.escape

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; max-width: 70em; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: left; }
th { background: #f0f0f0; }
pre, code { background: #f6f6f6; } pre { padding: 0.6em; overflow-x: auto; }
nav { margin-bottom: 1em; } .state { font-weight: bold; }
label { display: block; margin: 0.3em 0; }
"""


def _doc(title: str, body: str, head: str = "") -> str:
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>{esc(title)}</title>{head}"
            f"<style>{STYLE}</style></head>\n<body>\n<nav><a href='/'>wfbench leaderboard</a></nav>\n{body}\n"
            "</body></html>\n")


def _table(table_id: str, header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{esc(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{esc(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table id='{table_id}'><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def track_info(board, name: str) -> dict[str, Any]:
    """What ``GET /api/tracks`` says of a track: its hash, seeds per phase and the test seeds' commitment."""
    t = board.tracks[name]
    dev = tuple(t.public_seeds)
    published = board.hidden_commitment(name)
    return {"name": name, "hash": t.hash, "description": t.description, "scenarios": len(t.configs()),
            "dev": {"seeds": f"{dev[0]}..{dev[-1]}", "count": len(dev)},
            "test": {"hidden": True, "count": published.count, "version": published.version,
                     "commitment": published.commitment}}


_RANK = threading.Lock()
# board -> {(track, phase): (what the ranking saw, the ranking)}, like the pages below
_RANKINGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _stamp(board, track: str, phase: str) -> tuple:
    """What a board's ranking and page depend on: the submissions' states and times and the hidden seeds."""
    return (tuple((s.id, s.state, s.updated) for s in board.submissions(track, phase)),
            board.hidden_commitment(track), board.test_phase_ended(track))


def board_ranking(board, track: str, phase: str) -> Ranking:
    """The ranking of a phase of ``track`` by the local board's own rules, ranked again only when a submission changed.

    Its stratified bootstrap takes seconds on a busy machine, and the JSON and the page both ask for it.
    """
    stamp = _stamp(board, track, phase)
    with _RANK:
        kept = _RANKINGS.setdefault(board, {})
        cached = kept.get((track, phase))
        if cached is None or cached[0] != stamp:
            kept[(track, phase)] = cached = (stamp, report.ranking(board, board.phase_track(track, phase),
                                                                   phase=phase))
    return cached[1]


def phase_note(board, track: str, phase: str) -> str:
    """The line above a board saying which seeds it ranks on (for the test phase: how many, and their commitment)."""
    t = board.tracks[track]
    if phase == "dev":
        seeds = tuple(t.public_seeds)
        return (f"Development phase: the public seeds {seeds[0]}..{seeds[-1]}; each submission's page shows its log "
                "and per-seed rows.")
    c = board.hidden_commitment(track)
    return (f"Test phase: {c.count} hidden seeds (version {c.version}), held by the server only; the seeds of the "
            f"caption below, 0..{c.count - 1}, are their indices. Only aggregates are shown. Commitment: "
            f"{c.commitment} (sha256 of the canonical JSON of the track, its hash, the version, the seeds and a salt, "
            "published before any result; revealing the seeds and salt later lets anyone check it).")


_RENDER = threading.Lock()  # pyplot's figures are global state: one board is drawn at a time
# board -> {(track, phase): (what the page showed, the page)}; a board that is gone takes its pages with it
_PAGES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def board_page(board, track: str, phase: str) -> str:
    """The board of ``track``'s ``phase`` (:func:`render_board`), drawn again only when a submission changed.

    Drawing a board (the ranking's bootstrap, the figures) takes most of a second; a
    board is asked for far more often than a submission changes, so the last page is
    kept per board, track and phase with the submissions' states and times it showed (a
    running entry's episode count is brought up to date when its state changes).
    """
    stamp = _stamp(board, track, phase)
    with _RENDER:
        pages = _PAGES.setdefault(board, {})
        cached = pages.get((track, phase))
        if cached is None or cached[0] != stamp:
            pages[(track, phase)] = cached = (stamp, render_board(board, track, phase))
    return cached[1]


def render_board(board, track: str, phase: str) -> str:
    """The board of ``track``'s ``phase``: the local report's page with the phase's note and links above it."""
    r = board_ranking(board, track, phase)
    page = report.render(r, "html", per_seed=phase == "dev")  # a test phase shows aggregates only
    other = "test" if phase == "dev" else "dev"
    banner = (f"<nav><a href='/'>wfbench leaderboard</a> | <a href='/board/{esc(track)}?phase={other}'>"
              f"{other} phase</a> | <a href='/api/board/{esc(track)}?phase={phase}'>JSON</a></nav>\n"
              f"<p id='phase' data-phase='{phase}'>{esc(phase_note(board, track, phase))}</p>\n")
    return page.replace("<body>\n", "<body>\n" + banner, 1)


def home_page(board, base: str, limit: int) -> str:
    """The tracks with links to their boards, how to submit with the client, and an upload form."""
    rows = []
    for name in board.tracks:
        info = track_info(board, name)
        rows.append(f"<tr><td>{esc(name)}</td><td>{esc(info['description'])}</td><td>{esc(info['hash'])}</td>"
                    f"<td><a href='/board/{esc(name)}?phase=dev'>dev ({esc(info['dev']['seeds'])})</a></td>"
                    f"<td><a href='/board/{esc(name)}?phase=test'>test ({info['test']['count']} hidden seeds)</a>"
                    f"<br><code>{esc(info['test']['commitment'])}</code></td></tr>")
    options = "".join(f"<option value='{esc(n)}'>{esc(n)}</option>" for n in board.tracks)
    first = next(iter(board.tracks), "paper-64")
    command = (f"wfbench leaderboard upload --server {base} --token TOKEN --policy mypkg.policy:MyPolicy "
               f"--track {first} --phase dev")
    body = f"""<h1>wfbench leaderboard</h1>
<h2>Tracks</h2>
<table id='tracks'><thead><tr><th>Track</th><th>Description</th><th>Hash</th><th>Development board</th>
<th>Test board and the hidden seeds' commitment</th></tr></thead><tbody>{"".join(rows)}</tbody></table>
<h2 id='how'>How to submit</h2>
<p>Ask the board's admin for a token, then, in the folder holding your policy's package:</p>
<pre id='command'>{esc(command)}</pre>
<p>The client packs the package of the entry point (code and checkpoint files, at most {limit / 2**20:g} MiB),
uploads it and follows the evaluation. It runs in a sandbox with no network, sees only observations and gets
opaque per-episode keys instead of seeds; <code>wfbench evaluate --sandbox</code> runs the same sandbox at home.
The development phase runs on the public seeds and shows your log; the test phase runs on hidden seeds, shows
only aggregates, and is limited per account (one running job, a daily quota); the development phase has a
quota too. The same package submitted twice by one account is evaluated once.</p>
<h2>Upload a package</h2>
<form id='upload' method='post' action='/submit' enctype='multipart/form-data'>
<label>Token <input name='token' type='password' required></label>
<label>Package (.zip or .whl with wfbench-policy.json) <input name='package' type='file' accept='.zip,.whl'
 required></label>
<label>Track <select name='track'>{options}</select></label>
<label>Phase <select name='phase'><option value='dev'>dev (public seeds)</option>
<option value='test'>test (hidden seeds)</option></select></label>
<label>Name (optional) <input name='name'></label>
<label>Entry point (optional, module:attr; default: the manifest's) <input name='entry'></label>
<button type='submit'>Submit</button>
</form>"""
    return _doc("wfbench leaderboard", body)


RESULT_HEADER = ["KPI", "Mean", "25%", "75%"]
ROW_SKIP = ("submission_id", "id")  # columns of the stored rows not worth a column on the page


def submission_page(sub: dict[str, Any]) -> str:
    """A submission's state, reason and aggregate; for the development phase its per-seed rows and its log.

    ``sub`` is the submission's JSON (:func:`wfbench.leaderboard.server.api.answers.submission_json`),
    which already leaves out what a test-phase submission may not show.
    """
    final = sub["state"] in ("done", "failed", "withdrawn")
    head = "" if final else f"<meta http-equiv='refresh' content='{REFRESH_S}'>"
    progress = sub["progress"]
    parts = [f"<h1>Submission {sub['id']}: {esc(sub['name'])}</h1>",
             f"<p>Track <a href='/board/{esc(sub['track'])}?phase={esc(sub['phase'])}'>{esc(sub['track'])}</a>, "
             f"{esc(sub['phase'])} phase; entry <code>{esc(sub['entry'])}</code>; package "
             f"<code>{esc(sub['package'])}</code>; submitted {esc(sub['created'])}.</p>",
             f"<p>State: <span id='state' class='state' data-state='{esc(sub['state'])}'>{esc(sub['state'])}</span>"
             f" (<span id='progress'>{progress['done']}/{progress['total']}</span> episodes)"
             + (f"; reason: <span id='reason'>{esc(sub['reason'])}</span>" if sub.get("reason") else "")
             + (f"; <span id='note'>{esc(sub['note'])}</span>" if sub.get("note") else "")
             + ("" if final else f"; this page reloads every {REFRESH_S} s") + "</p>"]
    if sub.get("result"):
        parts += [f"<h2>Result over {sub['result'].get('episodes', '?')} episodes</h2>",
                  _table("result", RESULT_HEADER, result_cells(sub["result"]))]
    if sub["phase"] == "dev":
        rows = sub.get("rows") or []
        if rows:
            cols = [c for c in rows[0] if c not in ROW_SKIP]
            parts += ["<h2>Per-seed rows (public seeds)</h2>",
                      _table("rows", cols, [[_fmt(r[c]) for c in cols] for r in rows])]
        parts += ["<h2>Log</h2>", f"<pre id='log'>{esc(sub.get('log') or '(empty)')}</pre>"]
    else:
        parts.append("<p id='hidden'>A test-phase submission shows only its aggregate: its per-seed rows and its "
                     "log stay on the server.</p>")
    return _doc(f"submission {sub['id']}", "\n".join(parts), head)


def result_cells(result: dict[str, Any]) -> list[list[str]]:
    """One row per KPI of a submission's aggregate (``kpis``: mean, 25% and 75% quantiles), its label first."""
    rows = []
    for k, v in (result.get("kpis") or {}).items():
        rows.append([KPI_LABELS.get(k, k), *(_fmt(v.get(q)) for q in ("mean", "q25", "q75"))])
    return rows


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4f}"
    return "-" if value is None else str(value)


def error_page(status: int, detail: str) -> str:
    return _doc(f"error {status}", f"<h1>Error {status}</h1><p id='detail'>{esc(detail)}</p>")
