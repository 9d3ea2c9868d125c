"""Leaderboard: store safety, isolated submissions, resume after kill -9, provenance checks, reports."""

from __future__ import annotations

import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from contextlib import closing
from pathlib import Path

import pytest
from wfbench.leaderboard.report import ranking, render
from wfbench.leaderboard.store import Store, StoreError
from wfbench.leaderboard.submit import SubmitError, submit
from wfbench.leaderboard.tracks import TRACKS, get_track, scenario_track

from wfbench.cli import main
from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution

ROOT = Path(__file__).resolve().parents[2]

TINY = scenario_track(
    name="tiny-test",
    config=ScenarioConfig.preset("small").replace(name="tiny-test", horizon=60),
    public_seeds=(100, 101),
    test_seeds=(0, 1, 2, 3),
    description="a small track for the tests",
    references={"tiny-test": (0.0, 1.0)},  # no published constants: the normalized score is the NSW
)


def integrity(path) -> str:
    """SQLite's own check of a board file."""
    with closing(sqlite3.connect(path)) as c:
        return c.execute("PRAGMA integrity_check").fetchone()[0]


def _fast(**kw):
    return dict(execution=Execution(backend="serial", chunk_size=1), **kw)


@pytest.fixture()
def db(tmp_path):
    return tmp_path / "lb.sqlite"


def test_tracks_are_defined_and_hashed():
    p = get_track("paper-64")
    assert p.config.grid_width == 64 and p.config.max_facilities == 50 and p.config.max_personnel == 50
    assert p.config.horizon == 800 and len(p.test_seeds) == 50
    assert not set(p.test_seeds) & set(p.public_seeds)
    large = get_track("large")
    assert large.config.grid_width == 256 and large.config.max_facilities >= 200 and large.config.max_personnel >= 200
    ns = get_track("nonstationary").config
    assert ns.request_schedule.kind == "drift" and ns.churn_schedule.kind == "drift"
    assert len({t.hash for t in TRACKS.values()}) == 4  # and suite-v1: tests/leaderboard/test_leaderboard_suite.py
    edited = scenario_track(p.name, p.config.replace(horizon=801), p.public_seeds, p.test_seeds, p.description)
    assert edited.hash != p.hash
    with pytest.raises(ValueError, match="unknown track 'nope'; available: paper-64, nonstationary, large, suite-v1"):
        get_track("nope")


@pytest.mark.slow
def test_submit_stores_a_row_per_seed_with_provenance(db):
    out = submit(TINY, "heuristic", "h", submitter="tester", db=db, **_fast())
    assert out.status == "complete" and out.stored_rows == 4 and out.new_rows == 4
    rows, refused = Store(db).results(TINY)
    assert refused == [] and sorted(rows["seed"]) == [0, 1, 2, 3]
    assert set(rows["track_hash"]) == {TINY.hash} and set(rows["submitter"]) == {"tester"}
    assert set(rows["policy"]) == {"heuristic"} and rows["wfbench_version"].notna().all()
    again = submit(TINY, "heuristic", "h", db=db, **_fast())
    assert again.status == "complete" and again.new_rows == 0



def _job(db, name):
    """The queue's job of the entry ``name`` and its submission's state, fault and stored reason."""
    import sqlalchemy as sa

    store = Store(db)
    sub = store.find(TINY.name, name)
    with store.engine.begin() as conn:
        job = conn.execute(sa.text("SELECT state, fence FROM jobs WHERE submission_id = :i"), {"i": sub.id}).one()
        state = conn.execute(sa.text("SELECT state, fault, kind, reason FROM submissions WHERE id = :i"),
                             {"i": sub.id}).one()
    store.close()
    return tuple(job), tuple(state)


@pytest.mark.slow
def test_a_local_submission_is_a_job_of_the_board_s_queue_run_by_its_worker(db, capsys):
    out = submit(TINY, "heuristic", "h", db=db, **_fast())
    assert out.status == "complete" and out.new_rows == 4
    assert _job(db, "h") == (("done", 1), ("done", "", "", "")), "queued, claimed once (fence 1) and finished"
    out = submit(TINY, "tests.lb_policies:Raises", "broken", db=db, **_fast())
    assert out.status == "failed" and str(ROOT) in out.reason, "the caller gets the whole reason"
    (job, fence), (state, fault, kind, reason) = _job(db, "broken")
    assert (job, state, fault, kind) == ("failed", "failed", "policy", "raised")
    assert reason.startswith("policy 'tests.lb_policies:Raises' failed in act at ") and str(ROOT) not in reason
    assert capsys.readouterr().err == "", "the in-process worker says nothing of its own"
    assert len(Store(db).results(TINY)[0]) == 4, "the failure left the other entry's rows as they were"

HOSTILE = ROOT / "tests" / "data" / "user_policies" / "hostile.py"


@pytest.mark.parametrize(
    ("name", "reason"),
    [
        ("Raises", f"failed in act at {HOSTILE}:"),
        ("Garbage", "returned a malformed action at step 0 (its act is at "),
        ("Hangs", "did not return from act within the act timeout of 2 s (stopped at "),
        ("EatsMemory", "ran out of memory in act at "),
    ],
)
@pytest.mark.slow
def test_a_misbehaving_policy_fails_alone(db, name, reason):
    good = submit(TINY, "heuristic", "good", db=db, **_fast())
    before = Store(db).results(TINY)[0]
    # small limits: each hostile policy must end well inside the two-minute wall time, by the
    # act timeout or the memory limit (the wall time would give another reason)
    policy = f"tests.data.user_policies.hostile:{name}"
    out = submit(TINY, policy, "bad", db=db, **_fast(act_timeout_s=2.0, memory_mb=1536, wall_time_s=120.0))
    assert out.status == "failed" and out.reason.startswith(f"policy {policy!r} ") and reason in out.reason, out.reason
    assert "\n" not in out.reason and out.trace.startswith("Traceback"), "one line stored, the whole trace returned"
    store = Store(db)
    after, refused = store.results(TINY)
    assert refused == []
    assert after[after["name"] == "good"].equals(before[before["name"] == "good"]), "other entries untouched"
    assert store.find(TINY.name, "good").status == good.status == "complete"
    assert store.find(TINY.name, "bad").status == "failed"
    assert integrity(db) == "ok"


@pytest.mark.slow
def test_unloadable_policy_is_a_user_error_and_stores_nothing(db):
    with pytest.raises(SubmitError, match=r"policy 'tests.lb_policies:import_fails' could not be loaded: "
                                          r"ImportError: this entry point cannot be loaded at .*lb_policies.py:\d+$"):
        submit(TINY, "tests.lb_policies:import_fails", "x", db=db, **_fast())
    with pytest.raises(SubmitError, match="unknown policy 'nope'"):
        submit(TINY, "nope", "x", db=db, **_fast())
    with pytest.raises(SubmitError, match=r"^execution = 'serial' is not allowed; allowed: an Execution$"):
        submit(TINY, "heuristic", "x", db=db, execution="serial")
    assert Store(db).submissions() == []


@pytest.mark.slow
def test_name_taken_by_another_policy(db):
    submit(TINY, "heuristic", "mine", db=db, **_fast())
    with pytest.raises(SubmitError, match=r"the name 'mine' on track tiny-test is taken by a different policy "
                                          r"\('heuristic', fingerprint [0-9a-f]{16}; now 'random', fingerprint "
                                          r"[0-9a-f]{16}: another registry name\); pass --replace .* or choose "
                                          r"another --name$"):
        submit(TINY, "random", "mine", db=db, **_fast())


@pytest.mark.slow
def test_kill_minus_9_loses_no_finished_seed_and_resume_completes(db, tmp_path):
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        from tests.leaderboard.test_leaderboard import TINY
        from wfbench.leaderboard.submit import submit
        from wfbench.harness.backends import Execution
        if __name__ == "__main__":
            submit(TINY, "tests.lb_policies:Slow", "slow", db={str(db)!r}, execution=Execution("serial", chunk_size=1))
    """))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True, cwd=ROOT)
    try:
        deadline = time.monotonic() + 120
        n = 0
        while time.monotonic() < deadline:
            if db.exists():
                try:
                    with sqlite3.connect(db, timeout=5) as c:
                        n = c.execute("SELECT COUNT(*) FROM rows").fetchone()[0]
                except sqlite3.OperationalError:
                    n = 0
            if n >= 1:
                break
            time.sleep(0.05)
        assert n >= 1, "no seed finished in time"
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # parent and child, mid-run
        proc.wait()
    store = Store(db)
    assert integrity(db) == "ok"
    rows, refused = store.results(TINY)
    kept = len(rows)
    assert refused == [] and kept >= 1
    assert store.find(TINY.name, "slow").status == "running"
    out = submit(TINY, "tests.lb_policies:Slow", "slow", db=db, **_fast())
    assert out.status == "complete" and out.stored_rows == 4 and out.new_rows == 4 - kept


@pytest.mark.slow
def test_rows_that_do_not_match_the_track_are_refused(db):
    submit(TINY, "heuristic", "h", db=db, **_fast())
    with sqlite3.connect(db) as c:
        c.execute("UPDATE rows SET seed = 77 WHERE seed = 1")
        c.execute("UPDATE rows SET nsw = 0.99 WHERE seed = 2")
    rows, refused = Store(db).results(TINY)
    assert sorted(rows["seed"]) == [0, 3]
    assert any("seed 77 is not a test seed" in m for m in refused)
    assert any("seed 2: its values do not match its digest (the row was edited)" in m for m in refused)
    newer = scenario_track(TINY.name, TINY.config.replace(horizon=61), TINY.public_seeds, TINY.test_seeds,
                           TINY.description)
    rows, refused = Store(db).results(newer)
    assert rows.empty and all("another version of track tiny-test" in m for m in refused) and len(refused) == 4


def test_store_refuses_foreign_and_newer_files(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("not a database\n")
    with pytest.raises(StoreError, match="not a wfbench store \\(not an SQLite database\\)"):
        Store(text)
    assert text.read_text() == "not a database\n"
    other = tmp_path / "other.sqlite"
    with sqlite3.connect(other) as c:
        c.execute("CREATE TABLE t (x)")
    with pytest.raises(StoreError, match="an SQLite database but not a wfbench store"):
        Store(other)
    newer = tmp_path / "newer.sqlite"
    Store(newer).close()
    with sqlite3.connect(newer) as c:
        c.execute("UPDATE alembic_version SET version_num = '9999'")  # a revision of a later wfbench
    with pytest.raises(StoreError, match="written by a newer wfbench \\(board schema 9999; this wfbench reads up to "):
        Store(newer)
    newer_store = tmp_path / "newer-store.sqlite"  # a sqlite3 store of a schema after 4
    with sqlite3.connect(newer_store) as c:
        c.execute("CREATE TABLE submissions (id)")
        c.execute("PRAGMA application_id = 1464222257")  # "WFB1"
        c.execute("PRAGMA user_version = 99")
    with pytest.raises(StoreError, match="written by a newer wfbench \\(store schema 99"):
        Store(newer_store)


@pytest.mark.slow
def test_full_disk_while_writing_loses_nothing(db):
    submit(TINY, "heuristic", "h", db=db, **_fast())
    store = Store(db)
    sub = store.find(TINY.name, "h")
    with store.engine.connect() as c:  # the pool hands this connection to the next write
        pages = c.exec_driver_sql("PRAGMA page_count").scalar()
        c.exec_driver_sql(f"PRAGMA max_page_count = {pages}")  # the "disk" is now full
    rows = [{"seed": 1000 + i, "workforce_cost": 1.0, "utilization": 0.5, "downtime": 0.1, "nsw": 0.5,
             "episode_length": 60, "invalid_actions": 0, "pad": "x"} for i in range(400)]
    with pytest.raises(StoreError, match="the disk is full"):
        store.add_results(sub, "0", rows)
    store.close()
    rows_after, refused = Store(db).results(TINY)
    assert len(rows_after) == 4 and refused == []


@pytest.mark.slow
def test_cli_errors_are_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    bad = tmp_path / "x.sqlite"
    bad.write_bytes(b"garbage" * 10)
    taken = tmp_path / "taken.sqlite"
    submit(TINY, "heuristic", "mine", db=taken, **_fast())
    monkeypatch.setitem(TRACKS, TINY.name, TINY)  # reachable from the command line for this test
    cases = [
        ["leaderboard", "submit", "--policy", "random", "--name", "mine", "--track", TINY.name, "--db", str(taken)],
        ["leaderboard", "show", "--track", "nope"],
        ["leaderboard", "show", "--db", str(bad)],
        ["leaderboard", "show", "--format", "pdf", "--db", str(tmp_path / "a.sqlite")],
        ["leaderboard", "submit", "--policy", "nope", "--name", "n", "--db", str(tmp_path / "a.sqlite")],
        ["leaderboard", "submit", "--policy", "heuristic", "--name", "n", "--track", "nope"],
        ["leaderboard", "submit", "--policy", "heuristic", "--name", "n", "--backend", "gpu"],
    ]
    for argv in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("wfbench: error: "), (argv, err)
    assert bad.read_bytes() == b"garbage" * 10
    assert len(Store(taken).results(TINY)[0]) == 4, "the taken entry is intact"


@pytest.mark.slow
def test_reports_in_every_format(db, tmp_path):
    for name in ("heuristic", "random"):
        submit(TINY, name, name, db=db, **_fast())
    submit(TINY, "tests.lb_policies:Raises", "broken", db=db, **_fast())
    r = ranking(Store(db), TINY)
    assert r.table["name"].tolist() == ["heuristic", "random", "broken"]
    assert r.table["rank"].tolist()[:2] == [1, 2] and r.table["ranked"].tolist() == [True, True, False]
    md = render(r, "md")
    assert "| 1 | heuristic |" in md and "(baseline)" in md
    assert "failed: policy 'tests.lb_policies:Raises' failed in act at" in md
    csv = render(r, "csv")
    assert csv.splitlines()[0].startswith("name,policy") and len(csv.splitlines()) == 4
    html = render(r, "html")
    assert html.count("<img") == 3 and "<table id='ranking'>" in html  # NSW, KPIs, paired differences


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    raise AssertionError("headless Chromium is needed for this test: apt-get install chromium (.ci/run does)")


@pytest.mark.slow
@pytest.mark.needs_browser
def test_html_report_renders_in_headless_chromium(db, tmp_path):
    for name in ("heuristic", "random", "solver"):
        submit(TINY, name, name, db=db, **_fast())
    page = tmp_path / "board.html"
    assert main(["leaderboard", "show", "--track", "paper-64", "--db", str(db), "--format", "html",
                 "--out", str(page)]) == 0  # an empty track still renders
    page.write_text(render(ranking(Store(db), TINY), "html"))
    out = subprocess.run(
        [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=5000", "--dump-dom",
         page.as_uri()], capture_output=True, text=True, timeout=120,
    )
    dom = out.stdout
    assert "<table id=\"ranking\">" in dom, out.stderr[-2000:]
    ranked, per_scenario = dom.split("<table id=\"scenarios\">")
    assert ranked.count("<tr>") == 4 and per_scenario.count("<tr>") == 4  # header + 3 entries, each
    # the IQM chart, and the scenario's per-seed KPIs and paired differences to the baseline
    assert 'data-images-decoded="3"' in dom, "the browser decoded the three embedded plots"


def _orphan_workers() -> set[int]:
    """Pool workers (multiprocessing or loky) whose parent is gone (re-parented to init)."""
    out = set()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ")
            ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if ppid == 1 and (b"multiprocessing.spawn" in cmd or b"loky" in cmd):
            out.add(int(d.name))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["heuristic", "tests.lb_policies:Raises"])
def test_a_submission_leaves_no_worker_processes_behind(db, policy):
    before = _orphan_workers()
    submit(TINY, policy, "pool", db=db, execution=Execution("process", workers=2, chunk_size=1))
    time.sleep(0.5)
    assert _orphan_workers() - before == set()


@pytest.mark.slow
def test_oracles_stand_apart_and_a_submission_cannot_claim_the_future(db):
    for name in ("heuristic", "oracle-dispatch"):
        submit(TINY, name, name, db=db, **_fast())
    with pytest.raises(SubmitError, match="declares reads_trace = True.*deployable policies only"):
        submit(TINY, "tests.lb_policies:ClaimsTheFuture", "claims", db=db, **_fast())
    assert Store(db).find(TINY.name, "claims") is None
    r = ranking(Store(db), TINY)
    t = r.table.set_index("name")
    assert t.loc["oracle-dispatch", "status"] == "complete" and not t.loc["oracle-dispatch", "deployable"]
    assert t.loc["heuristic", "rank"] == 1 and not t.loc["oracle-dispatch", "ranked"]
    assert t.loc["oracle-dispatch", "nsw"] > t.loc["heuristic", "nsw"]  # it would have ranked first
    for fmt in ("table", "md"):
        ranked, _, reference = render(r, fmt).partition("Not deployable (reads the future)")
        assert "heuristic" in ranked and "oracle-dispatch" not in ranked, fmt
        assert "oracle-dispatch" in reference and "| 1 | heuristic" not in reference, fmt
    html = render(r, "html")
    assert html.index("<table id='ranking'>") < html.index("Not deployable") < html.index("<table id='reference'>")
    assert "oracle-dispatch" in html[html.index("<table id='reference'>"):]
