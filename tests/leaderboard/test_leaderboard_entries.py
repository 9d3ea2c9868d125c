"""Leaderboard entries are identified by what they run: fingerprints, --replace, withdraw, the audit trail,
legacy entries, and an honest HTML board (issue #26)."""

from __future__ import annotations

import json
import re
import sqlite3

import pytest
from wfbench.leaderboard.report import ORACLE_LABEL, iqm_figure, ranking, render
from wfbench.leaderboard.rows import KPI_COLUMNS, StoreError, row_digest, scrub_paths
from wfbench.leaderboard.schema4 import APPLICATION_ID
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.submit import policy_fingerprint, submit
from wfbench.leaderboard.tracks import TRACKS

from tests.leaderboard.test_leaderboard import ROOT, TINY, _fast, integrity
from tests.leaderboard.test_leaderboard_suite import _row
from tests.leaderboard.test_schema4_import import write_schema4
from wfbench.cli import main

POLICY = """
from wfbench.policies import get
from {module}_helper import INNER


class Mine:
    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self):
        self.inner = get(INNER)

    def reset(self, seeds):
        self.inner.reset(seeds)

    def act(self, obs):
        return self.inner.act(obs)
"""


@pytest.fixture()
def db(tmp_path):
    return tmp_path / "lb.sqlite"


@pytest.fixture()
def user_folder(tmp_path, monkeypatch):
    """A user's folder with a policy module that imports a helper module next to it; the cwd during the test."""
    folder = tmp_path / "work"
    folder.mkdir()
    module = "lbfp_mine"
    (folder / f"{module}.py").write_text(POLICY.format(module=module))
    (folder / f"{module}_helper.py").write_text('INNER = "heuristic"\n')
    monkeypatch.chdir(folder)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setitem(TRACKS, TINY.name, TINY)  # reachable from the command line
    return folder, module


def _cli_submit(module, db, *extra):
    return main(["leaderboard", "submit", "--policy", f"{module}:Mine", "--name", "mine", "--track", TINY.name,
                 "--db", str(db), "--backend", "serial", "--no-progress", *extra])


@pytest.mark.slow
def test_an_edited_policy_is_refused_under_its_name_until_replaced(user_folder, db, capsys):
    folder, module = user_folder
    assert _cli_submit(module, db) == 0
    assert "complete, 4 seeds stored (4 new)" in capsys.readouterr().out
    store = Store(db)
    before = store.results(TINY)[0].set_index("seed")["nsw"]
    sub = store.find(TINY.name, "mine")
    detail = json.loads(sub.fingerprint_detail)
    assert re.fullmatch(r"[0-9a-f]{16}", sub.fingerprint) and detail["kind"] == "entry-point"
    assert set(detail["files"]) == {module, f"{module}_helper"}, "the module and the user's file it imports only"

    # the same code again: resumed, nothing evaluated
    assert _cli_submit(module, db) == 0
    assert "complete, 4 seeds stored (0 new)" in capsys.readouterr().out
    kept = Store(db).find(TINY.name, "mine")
    assert (kept.id, kept.fingerprint, kept.fingerprint_detail, kept.status) == \
        (sub.id, sub.fingerprint, sub.fingerprint_detail, "complete")

    # the helper it imports changes what it runs: refused with one line, the entry kept as it was
    (folder / f"{module}_helper.py").write_text('INNER = "random"\n')
    assert _cli_submit(module, db) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured.err
    assert captured.err.startswith("wfbench: error: the name 'mine' on track tiny-test is taken by a different "
                                   f"policy ('{module}:Mine', fingerprint {sub.fingerprint}; now '{module}:Mine'")
    assert f"changed: {module}_helper)" in captured.err
    assert "pass --replace to evaluate this policy under that name" in captured.err
    assert "or choose another --name" in captured.err
    assert Store(db).find(TINY.name, "mine") == kept
    assert Store(db).results(TINY)[0].set_index("seed")["nsw"].equals(before)
    assert Store(db).audit().empty

    # --replace: the old rows go to the audit table, every seed is evaluated by the new code
    assert _cli_submit(module, db, "--replace") == 0
    assert "complete, 4 seeds stored (4 new)" in capsys.readouterr().out
    store = Store(db)
    new = store.find(TINY.name, "mine")
    assert new.fingerprint != sub.fingerprint and new.status == "complete"
    rows, refused = store.results(TINY)
    assert refused == [] and set(rows["fingerprint"]) == {new.fingerprint}
    direct = submit(TINY, "random", "random", db=db, **_fast())  # what the edited policy runs, scored apart
    assert direct.status == "complete"
    rows = store.results(TINY)[0]
    mine = rows[rows["name"] == "mine"].set_index("seed")["nsw"]
    assert mine.equals(rows[rows["name"] == "random"].set_index("seed")["nsw"].rename("nsw"))
    audit = store.audit(TINY.name)
    assert len(audit) == 4 and set(audit["action"]) == {"replaced"} and set(audit["fingerprint"]) == {sub.fingerprint}
    assert audit.set_index("seed")["nsw"].equals(before)
    assert integrity(db) == "ok"


@pytest.mark.slow
def test_the_same_policy_resumes_with_the_missing_seeds_only(db):
    first = submit(TINY, "tests.lb_policies:Slow", "slow", db=db, **_fast())
    assert first.status == "complete" and first.action == "new"
    with sqlite3.connect(db) as c:
        c.execute("DELETE FROM rows WHERE seed IN (1, 3)")  # as if the run had been killed before them
    again = submit(TINY, "tests.lb_policies:Slow", "slow", db=db, **_fast())
    assert (again.status, again.action, again.new_rows, again.stored_rows) == ("complete", "resumed", 2, 4)
    assert Store(db).audit().empty
    # a built-in resumes without starting a child, and is refused under a taken name too
    submit(TINY, "heuristic", "h", db=db, **_fast())
    assert submit(TINY, "heuristic", "h", db=db, **_fast()).new_rows == 0


def test_fingerprint_rule_for_files_checkpoints_and_builtins(tmp_path):
    tuned = tmp_path / "t.json"
    tuned.write_text('{"a": 1}')
    fp1, detail = policy_fingerprint(str(tuned))
    assert detail["kind"] == "tuned-file" and "code" in detail
    tuned.write_text('{"a": 2}')
    assert policy_fingerprint(str(tuned))[0] != fp1, "a tuned file's bytes"
    ckpt = tmp_path / "a" / "best.pt"
    ckpt.parent.mkdir()
    ckpt.write_bytes(b"weights-1")
    moved = tmp_path / "b.pt"
    moved.write_bytes(b"weights-1")
    assert policy_fingerprint(f"ppo:{ckpt}")[0] == policy_fingerprint(f"ppo:{moved}")[0], "bytes, not the path"
    assert policy_fingerprint(f"ppo:{ckpt}")[0] != policy_fingerprint(f"ppo:{ckpt}@greedy")[0], "the mode counts"
    moved.write_bytes(b"weights-2")
    assert policy_fingerprint(f"ppo:{ckpt}")[0] != policy_fingerprint(f"ppo:{moved}")[0]
    h, hd = policy_fingerprint("heuristic")
    assert hd["kind"] == "builtin" and h != policy_fingerprint("random")[0]
    assert "file" in policy_fingerprint("heuristic-tuned")[1], "a shipped tuned file's bytes"



def test_the_oracle_fingerprint_covers_the_files_of_its_candidates(tmp_path, monkeypatch):
    """The oracle plays the shipped networks and tuned files: a changed one changes its numbers, so its fingerprint."""
    from wfbench.policies import registry

    before, detail = policy_fingerprint("oracle")
    assert set(detail["candidates"]) == set(registry.oracle_candidates())
    tuned_dir = tmp_path / "tuned"
    tuned_dir.mkdir()
    files = [registry.tuned_file(n).name for n in registry.names_of("tuned")]
    for file in files:
        (tuned_dir / file).write_bytes((registry._tuned.TUNED_DIR / file).read_bytes())
    monkeypatch.setattr(registry._tuned, "TUNED_DIR", tuned_dir)
    assert policy_fingerprint("oracle")[0] == before, "the same bytes elsewhere: the same fingerprint"
    first = files[0]
    (tuned_dir / first).write_bytes((tuned_dir / first).read_bytes() + b"\n")
    assert policy_fingerprint("oracle")[0] != before, "an edited candidate file must change the oracle's fingerprint"

@pytest.mark.slow
def test_withdraw_moves_the_entry_to_the_audit_table(db, capsys, monkeypatch):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)
    for name in ("heuristic", "random"):
        submit(TINY, name, name, db=db, **_fast())
    argv = ["leaderboard", "withdraw", "--track", TINY.name, "--db", str(db)]
    assert main([*argv, "--name", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: no entry 'nope' on track tiny-test in "), err
    assert err.rstrip().endswith("entries there: heuristic, random"), err
    assert main([*argv, "--name", "random", "--reason", "tuned on the test seeds"]) == 0
    assert "withdrew 'random' from track tiny-test: its entry and 4 rows moved to the audit tables" in \
        capsys.readouterr().out
    store = Store(db)
    assert store.find(TINY.name, "random") is None
    assert ranking(store, TINY).table["name"].tolist() == ["heuristic"]
    audit = store.audit(TINY.name)
    assert len(audit) == 4 and set(audit["action"]) == {"withdrawn"}
    assert set(audit["note"]) == {"tuned on the test seeds"} and audit["moved_at"].notna().all()
    assert main(["leaderboard", "withdraw", "--name", "x", "--db", str(db.parent / "none.sqlite")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err
    assert not (db.parent / "none.sqlite").exists()
    # the name is free again
    assert submit(TINY, "random", "random", db=db, **_fast()).action == "new"


# the schema that wfbench wrote before fingerprints (store schema 1), as it was
SCHEMA_1 = f"""
CREATE TABLE submissions (
    id INTEGER PRIMARY KEY, track TEXT NOT NULL, name TEXT NOT NULL, policy TEXT NOT NULL, submitter TEXT NOT NULL,
    track_hash TEXT NOT NULL, wfbench_version TEXT NOT NULL, created_at TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('running', 'complete', 'failed')), reason TEXT NOT NULL DEFAULT '',
    builtin INTEGER NOT NULL DEFAULT 0, UNIQUE (track, name));
CREATE TABLE results (
    submission_id INTEGER NOT NULL REFERENCES submissions(id), seed INTEGER NOT NULL, track TEXT NOT NULL,
    track_hash TEXT NOT NULL, policy TEXT NOT NULL, submitter TEXT NOT NULL, wfbench_version TEXT NOT NULL,
    finished_at TEXT NOT NULL, workforce_cost REAL NOT NULL, utilization REAL NOT NULL, downtime REAL NOT NULL,
    nsw REAL NOT NULL, episode_length INTEGER NOT NULL, invalid_actions INTEGER NOT NULL, digest TEXT NOT NULL,
    PRIMARY KEY (submission_id, seed));
PRAGMA application_id = {APPLICATION_ID};
PRAGMA user_version = 1;
"""


def _schema_1_store(path, name="old", policy="heuristic", nsw=0.99):
    with sqlite3.connect(path) as c:
        c.executescript(SCHEMA_1)
        c.execute("INSERT INTO submissions VALUES (1, ?, ?, ?, 'me', ?, '0.1.0', '2024-01-01', 'complete', '', 0)",
                  (TINY.name, name, policy, TINY.hash))
        for seed in TINY.test_seeds:
            v = {"workforce_cost": 1.0, "utilization": 0.5, "downtime": 0.1, "nsw": nsw, "episode_length": 60,
                 "invalid_actions": 0}
            d = row_digest(name, TINY.name, TINY.hash, policy, "me", "0.1.0", seed, v)
            c.execute("INSERT INTO results VALUES (1, ?, ?, ?, ?, 'me', '0.1.0', 't', 1.0, 0.5, 0.1, ?, 60, 0, ?)",
                      (seed, TINY.name, TINY.hash, policy, nsw, d))


def test_a_store_before_schema_4_is_refused_with_one_line_and_left_as_it_was(db):
    _schema_1_store(db)
    before = db.read_bytes()
    with pytest.raises(StoreError, match=r"is a store of schema 1, which this wfbench does not import \(it imports "
                                         r"schema 4\); open it once with an earlier wfbench \(before issue #45\) to "
                                         r"upgrade it to schema 4 first$"):
        Store(db)
    assert db.read_bytes() == before


@pytest.mark.slow
def test_an_imported_legacy_entry_is_re_evaluated_on_resubmission(db):
    write_schema4(db)  # its entry 'old' was stored without a fingerprint (random, nsw 0.3 + 0.01 x seed)
    store = Store(db)
    old = store.find(TINY.name, "old")
    assert old.legacy and old.fingerprint == ""
    r = ranking(store, TINY)
    assert r.table.set_index("name").loc["old", "fingerprint"] == "legacy"
    assert "complete (legacy: no fingerprint)" in render(r, "md")
    before = set(store.results(TINY)[0].query("name == 'old'")["nsw"])
    store.close()
    # the first resubmission cannot tell whether the legacy rows are this code's: it evaluates every seed anew
    out = submit(TINY, "random", "old", db=db, **_fast())
    assert (out.status, out.action, out.new_rows) == ("complete", "legacy", 4)
    store = Store(db)
    rows = store.results(TINY)[0]
    assert not before & set(rows.query("name == 'old'")["nsw"]) and not store.find(TINY.name, "old").legacy
    audit = store.audit(TINY.name).query("name == 'old'")
    assert len(audit) == 4 and set(audit["nsw"]) == before
    assert audit["note"].str.contains("without a fingerprint").all()
    # the next one resumes
    assert submit(TINY, "random", "old", db=db, **_fast()).action == "resumed"


def test_the_board_spells_the_kpi_table_in_its_rows_table(db):
    import sqlalchemy as sa

    store = Store(db)
    columns = [c["name"] for c in sa.inspect(store.engine).get_columns("rows")]
    assert [c for c in columns if c in KPI_COLUMNS] == list(KPI_COLUMNS)
    # the KPI columns of schema 4, which an imported store's rows fill: a KPI added to wfbench/core/kpis.py needs a
    # migration of the board's rows table, and the import a value for it
    assert KPI_COLUMNS == ("workforce_cost", "utilization", "downtime", "nsw")
    store.close()


def test_the_iqm_chart_sets_oracles_apart(db):
    store = Store(db)
    for name, nsw in (("heuristic", 0.6), ("oracle-dispatch", 0.8)):
        sub, _ = store.open_submission(TINY, name, name, "me", "0", fingerprint=name)
        store.add_results(sub, "0", [_row("", s, nsw + 0.01 * s) for s in TINY.test_seeds])
        store.set_status(sub.id, "done")
    r = ranking(store, TINY, reps=200)
    ax = iqm_figure(r).axes[0]
    bars = {label.get_text(): patch for label, patch in zip(ax.get_xticklabels(), ax.patches, strict=True)}
    assert set(bars) == {"heuristic", "oracle-dispatch"}  # one bar each: a one-scenario track ranks over all
    # TINY's references are (0, 1): the normalized score is the NSW, and the IQM of 4 seeds the mean of the middle 2
    assert bars["heuristic"].get_height() == pytest.approx(0.615) and bars["oracle-dispatch"].get_height() == \
        pytest.approx(0.815)
    assert bars["oracle-dispatch"].get_hatch() and not bars["heuristic"].get_hatch()
    assert bars["oracle-dispatch"].get_facecolor() != bars["heuristic"].get_facecolor()
    assert ORACLE_LABEL == "reads the future, not deployable"
    assert ORACLE_LABEL in [t.get_text() for t in ax.get_legend().get_texts()]
    assert [t.get_text() for t in ax.get_legend().get_texts()][0] == "all scenarios"


@pytest.mark.slow
def test_the_board_shows_no_absolute_path(db, monkeypatch):
    monkeypatch.chdir(ROOT)  # the submission's working folder: stored paths are relative to it
    submit(TINY, "tests.lb_policies:Raises", "broken", db=db, **_fast())
    store = Store(db)
    sub = store.find(TINY.name, "broken")
    assert "tests/lb_policies.py:" in sub.reason and str(ROOT) not in sub.reason, "stored relative to the cwd"
    # a reason stored with a path elsewhere on the submitter's machine (an older wfbench stored them whole)
    store.set_status(sub.id, "failed", f"policy 'x' failed in act at {ROOT}/tests/lb_policies.py:25: boom; "
                                       "also /home/someone/private/mod.py:3")
    r = ranking(store, TINY)
    for fmt in ("table", "md", "csv", "html"):
        text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", render(r, fmt))
        assert str(ROOT) not in text and "/home/someone" not in text, fmt
        assert "lb_policies.py:25" in text and "mod.py:3" in text, fmt
        assert not re.search(r"(?<![\w.<])/[\w.-]+/[\w.-]+", text.replace("</", "")), fmt


def test_scrub_paths():
    assert scrub_paths("at /a/b/c.py:3: x 1/2 and ppo:runs/best.pt") == "at c.py:3: x 1/2 and ppo:runs/best.pt"
    assert scrub_paths("at /w/p/m.py:3", "/w") == "at p/m.py:3"
    assert scrub_paths("ppo:/home/me/best.pt@greedy") == "ppo:best.pt@greedy"
