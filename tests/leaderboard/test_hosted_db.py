"""The hosted board's database (issue #34): URLs, hashed tokens, packages by hash, dedupe, quotas, hidden seeds, views.

Every test that touches a database runs on SQLite and on PostgreSQL (the ``postgres_url``
fixture of tests/conftest.py).
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
import threading
from pathlib import Path

import pytest
import sqlalchemy as sa
from wfbench.leaderboard.board import hidden, queue
from wfbench.leaderboard.board.db import Board, BoardError, QuotaExceeded, connect, submissions
from wfbench.leaderboard.report import ranking, render
from wfbench.leaderboard.store import KPI_COLUMNS
from wfbench.leaderboard.tracks import scenario_track, suite_track

from wfbench.core.config import ScenarioConfig

TINY = scenario_track(name="tiny", config=ScenarioConfig.preset("small").replace(name="tiny", horizon=20),
                      public_seeds=(1000, 1001, 1002), test_seeds=(0, 1, 2), description="a tiny track for the tests",
                      references={"tiny": (0.0, 1.0)})  # no published constants: normalized = NSW


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY}, daily_quota=2)


def fake_rows(units, nsw):
    """Rows for ``units`` ((scenario, seed index, seed)) whose NSW is ``nsw`` + index / 100."""
    return [{"scenario": sc, "seed_index": i, "seed": s, **{k: 0.5 for k in KPI_COLUMNS}, "nsw": nsw + i / 100,
             "episode_length": 20, "invalid_actions": 0, "decision_ms_p50": 0.1, "decision_ms_p99": 0.2,
             "cpu_s": 0.01, "machine": "test machine"} for sc, i, s in units]


def run_fake(board, sub, nsw, state="done", reason=""):
    """Play a worker: claim the submission's job, store fake rows, finish it."""
    c = queue.claim(board.engine, "tester", 30)
    assert c is not None and c.submission_id == sub.id
    queue.write_rows(c, fake_rows(board.units(sub), nsw))
    queue.finish(c, state, reason, {"fake": True} if state == "done" else None)


# -- connecting ---------------------------------------------------------------------------------------------


def test_connect__other_urls_are_refused_with_the_allowed_forms():
    for bad in ("mysql://u:secretpw@h/db", "postgresql://u@h/db", ":memory:", "sqlite:///:memory:"):
        with pytest.raises(BoardError) as e:
            connect(bad)
        assert "allowed: a file path or sqlite:///PATH (SQLite), or postgresql+psycopg://" in e.value.reason
        assert "secretpw" not in e.value.reason, "the password is never echoed"
        assert "\n" not in e.value.reason


def test_connect__sqlite_is_wal_with_foreign_keys_and_every_transaction_takes_the_write_lock(tmp_path):
    engine = connect(tmp_path / "b.sqlite")
    with engine.begin() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        conn.exec_driver_sql("SELECT 1")  # a read-only transaction...
        other = sqlite3.connect(tmp_path / "b.sqlite", timeout=0.05, isolation_level=None)
        with pytest.raises(sqlite3.OperationalError, match="locked"):
            other.execute("BEGIN IMMEDIATE")  # ...already holds the single writer's lock (BEGIN IMMEDIATE)
        other.close()
    engine.dispose()


class _Cursor:
    """A cursor whose first ``locked`` executes fail as SQLite's WAL switch does while another connection opens."""

    def __init__(self, locked: int, message: str = "database is locked"):
        self.locked, self.message, self.calls = locked, message, 0

    def execute(self, sql):
        self.calls += 1
        if self.calls <= self.locked:
            raise sqlite3.OperationalError(self.message)


def test_connect__the_switch_to_wal_waits_out_another_connections_lock_and_nothing_else():
    from wfbench.leaderboard.board.db import _to_wal

    cur = _Cursor(locked=3)
    _to_wal(cur)  # a start beside three others: it waits, as every statement waits on a lock
    assert cur.calls == 4
    other = _Cursor(locked=1, message="disk I/O error")
    with pytest.raises(sqlite3.OperationalError, match="disk I/O"):
        _to_wal(other)  # any other failure is the caller's at once
    assert other.calls == 1


# -- accounts and packages ----------------------------------------------------------------------------------


def test_tokens_are_stored_only_as_their_hash(board):
    token = board.add_account("alice")
    acct = board.account(token)
    assert acct is not None and acct.name == "alice" and not acct.admin
    assert board.account(token + "x") is None and board.account("") is None
    with board.engine.begin() as conn:
        stored = conn.execute(sa.text("SELECT name, token_hash FROM accounts")).all()
    assert stored == [("alice", hashlib.sha256(token.encode()).hexdigest())]
    if board.engine.dialect.name == "sqlite":
        board.close()
        files = Path(board.engine.url.database).parent.glob("board.sqlite*")  # the file, and its WAL if any
        assert not any(token.encode() in f.read_bytes() for f in files), "the token is nowhere in the files"
    with pytest.raises(BoardError, match="account name 'alice' is taken; choose another"):
        board.add_account("alice")
    with pytest.raises(BoardError, match=r"account name 'a\\nb' is not allowed; allowed: 1-100 characters on one"):
        board.add_account("a\nb")


def test_packages_are_stored_once_by_content_hash(board):
    sha = board.put_package(b"PK fake package")
    assert sha == "sha256:" + hashlib.sha256(b"PK fake package").hexdigest()
    assert board.put_package(b"PK fake package") == sha
    assert board.package(sha) == b"PK fake package" and board.package("sha256:00") is None
    with board.engine.begin() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM packages")).scalar() == 1


# -- submissions --------------------------------------------------------------------------------------------


def test_the_same_package_entry_track_and_phase_is_submitted_once_per_account(board):
    alice, bob = (board.account(board.add_account(n)) for n in ("alice", "bob"))
    sha = board.put_package(b"pkg")
    first, created = board.submit(alice, "tiny", "dev", sha, "mypkg:Policy", "mine")
    assert created and first.state == "queued" and first.reason == "" and first.account == "alice"
    again, created = board.submit(alice, "tiny", "dev", sha, "mypkg:Policy", "another name")
    assert not created and again.id == first.id and again.name == "mine", "the existing submission, not a new one"
    other, created = board.submit(alice, "tiny", "dev", sha, "mypkg:Other", "mine")
    assert created and other.id != first.id, "another entry point is another submission"
    theirs, created = board.submit(bob, "tiny", "dev", sha, "mypkg:Policy", "bobs")
    assert created and theirs.account == "bob", "another account's identical bytes are its own entry (issue #42)"
    with board.engine.begin() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM jobs")).scalar() == 3


def test_concurrent_submissions_of_one_package_store_one_per_account(board):
    accts = [board.account(board.add_account(f"user{i}")) for i in range(2)]
    sha = board.put_package(b"same bytes")
    got, errors = [], []

    def go(a):
        try:
            got.append(board.submit(a, "tiny", "dev", sha, "p:P", "x"))
        except Exception as exc:  # noqa: BLE001 - any error fails the test below
            errors.append(exc)

    threads = [threading.Thread(target=go, args=(accts[i % 2],)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len({s.id for s, _ in got}) == 2 and sum(created for _, created in got) == 2
    assert sorted(s.account for s in board.submissions("tiny", "dev")) == ["user0", "user1"]


def test_bad_submissions_say_what_is_allowed(board):
    alice = board.account(board.add_account("alice"))
    sha = board.put_package(b"pkg")
    with pytest.raises(BoardError, match="unknown track 'paper-64'; available: tiny"):
        board.submit(alice, "paper-64", "dev", sha, "p:P", "x")
    with pytest.raises(BoardError, match="phase 'final' is not allowed; allowed: dev, test"):
        board.submit(alice, "tiny", "final", sha, "p:P", "x")
    with pytest.raises(BoardError, match="no package 'sha256:ff' on this board; upload the package first"):
        board.submit(alice, "tiny", "dev", "sha256:ff", "p:P", "x")
    with pytest.raises(BoardError, match="submission name '' is not allowed"):
        board.submit(alice, "tiny", "dev", sha, "p:P", "")
    # a namesake of a built-in would hide the baseline the reports compare with
    with pytest.raises(BoardError, match=r"^the name 'heuristic' is kept for the built-in entry of that policy; "
                                         r"allowed: any other name \(--name\)$"):
        board.submit(alice, "tiny", "dev", sha, "p:P", "heuristic")


def test_test_phase_allows_one_job_at_a_time_per_account(board):
    alice, bob = (board.account(board.add_account(n)) for n in ("alice", "bob"))
    a, b = board.put_package(b"a"), board.put_package(b"b")
    first, _ = board.submit(alice, "tiny", "test", a, "p:P", "one")
    with pytest.raises(QuotaExceeded) as e:
        board.submit(alice, "tiny", "test", b, "p:P", "two")
    assert e.value.reason == (f"one test-phase job at a time per account: submission {first.id} is still queued; "
                              "submit again once it is done or failed")
    assert board.submit(alice, "tiny", "test", a, "p:P", "one")[1] is False, "a dedupe hit is never refused"
    assert board.submit(bob, "tiny", "test", b, "p:P", "two")[1], "another account has its own quota"
    assert board.submit(alice, "tiny", "dev", b, "p:P", "two")[1], "the dev phase has no quota"
    assert len(board.submissions("tiny", "test")) == 2


def test_test_phase_daily_quota(board):
    alice = board.account(board.add_account("alice"))
    board.ensure_hidden_seeds("tiny", n=2)
    shas = [board.put_package(bytes([i])) for i in range(3)]
    for sha in shas[:2]:
        sub, _ = board.submit(alice, "tiny", "test", sha, "p:P", sha[-6:])
        run_fake(board, sub, 0.5)
    with pytest.raises(QuotaExceeded, match=r"daily quota reached: 2 test-phase submissions in the last 24 h "
                                            r"\(allowed: 2\); the next one is allowed in 14\d\d min"):
        board.submit(alice, "tiny", "test", shas[2], "p:P", "third")
    with board.engine.begin() as conn:  # a day later
        conn.execute(submissions.update().values(created=submissions.c.created - 86400 - 1))
    assert board.submit(alice, "tiny", "test", shas[2], "p:P", "third")[1]


# -- hidden seeds -------------------------------------------------------------------------------------------


def test_hidden_seeds_are_committed_and_verifiable(board):
    h = board.ensure_hidden_seeds("tiny", n=8)
    assert h.version == 1 and len(set(h.seeds)) == 8
    assert all(hidden.SEED_LOW <= s < hidden.SEED_HIGH for s in h.seeds)
    assert board.ensure_hidden_seeds("tiny", n=3) == h, "the stored list, whatever n"
    pub = board.hidden_commitment("tiny")
    assert pub == hidden.Commitment("tiny", TINY.hash, 1, 8, h.commitment)
    canonical = json.dumps({"track": "tiny", "track_hash": TINY.hash, "version": 1, "seeds": list(h.seeds),
                            "salt": h.salt}, sort_keys=True, separators=(",", ":"))
    assert pub.commitment == "sha256:" + hashlib.sha256(canonical.encode()).hexdigest()
    assert hidden.verify(pub, h.seeds, h.salt)
    assert not hidden.verify(pub, (h.seeds[0] + 1, *h.seeds[1:]), h.salt), "another seed list does not verify"
    assert not hidden.verify(pub, h.seeds, "00" * 16)
    # a new definition of the track needs a new list; the old one stays for the submissions that ran on it
    edited = scenario_track("tiny", TINY.config.replace(horizon=21), TINY.public_seeds, TINY.test_seeds,
                            TINY.description)
    other = Board(board.url, tracks={"tiny": edited})
    h2 = other.ensure_hidden_seeds("tiny", n=4)
    assert h2.version == 2 and h2.track_hash == edited.hash and not set(h2.seeds) & set(h.seeds)
    assert other.hidden_commitment("tiny").version == 2 and board.hidden_commitment("tiny").version == 1
    other.close()


def test_a_test_phase_submission_never_returns_its_seeds(board):
    alice = board.account(board.add_account("alice"))
    h = board.ensure_hidden_seeds("tiny", n=3)
    dev, _ = board.submit(alice, "tiny", "dev", board.put_package(b"d"), "p:P", "d")
    run_fake(board, dev, 0.4)
    test, _ = board.submit(alice, "tiny", "test", board.put_package(b"t"), "p:P", "t")
    assert test.hidden_version == 1
    run_fake(board, test, 0.4)
    assert board.rows(dev.id)["seed"].tolist() == [1000, 1001, 1002]
    rows = board.rows(test.id)
    assert "seed" not in rows and rows["seed_index"].tolist() == [0, 1, 2]
    track = board.phase_track("tiny", "test")
    frame, _ = board.results(track, "test")
    assert frame["seed"].tolist() == [0, 1, 2] and track.test_seeds == (0, 1, 2)
    r = ranking(board, track, phase="test")
    shown = render(r, "table") + render(r, "csv")
    assert h.commitment in shown, "the test board names the commitment"
    assert not any(str(s) in shown for s in h.seeds), "no hidden seed reaches the board"


def test_a_phase_ranks_like_the_local_board(board):
    alice, bob = (board.account(board.add_account(n)) for n in ("alice", "bob"))
    subs = [board.submit(a, "tiny", "dev", board.put_package(name.encode()), f"{name}:P", name)[0]
            for a, name in ((alice, "low"), (bob, "high"), (alice, "broken"), (bob, "waiting"))]
    run_fake(board, subs[0], 0.3)
    run_fake(board, subs[1], 0.6)
    c = queue.claim(board.engine, "tester", 30)
    queue.finish(c, "failed", "the policy raised ValueError: nope at p.py:3")
    again = board.submit(alice, "tiny", "dev", board.put_package(b"x"), "x:P", "high")[0]  # a name used twice
    r = ranking(board, board.phase_track("tiny", "dev"), phase="dev")
    table = r.table.set_index("name")
    assert r.table["name"].tolist()[:2] == [f"high #{subs[1].id}", "low"], "ranked by mean NSW"
    assert table.loc["low", "nsw"] == pytest.approx(0.31) and table.loc["low", "rank"] == 2
    assert table.loc["broken", "status"] == "failed" and "ValueError: nope" in table.loc["broken", "reason"]
    assert table.loc["waiting", "status"] == "running" and table.loc[f"high #{again.id}", "status"] == "running"
    assert table.loc["low", "submitter"] == "alice" and table.loc["low", "policy"] == "low:P"
    assert "development phase on the public seeds" in render(r, "table")


def test_board_tracks_carry_what_the_rows_carry_as_seed():
    dev = hidden.board_track(TINY, "dev")
    test = hidden.board_track(TINY, "test", 4, "commitment sha256:ab")
    assert dev.test_seeds == TINY.public_seeds and test.test_seeds == (0, 1, 2, 3)
    assert test.description.endswith("; commitment sha256:ab") and test.config == TINY.config
    suite = suite_track("suite-v1")
    st = hidden.board_track(suite, "test", 2)
    assert st.test_seeds == (0, 1) and st.units() == [(sc, s) for sc in suite.configs() for s in (0, 1)]
    assert hidden.units(TINY, (7, 9)) == [("", 0, 7), ("", 1, 9)]
    assert hidden.key_context("tiny", "test") != hidden.key_context("tiny", "dev")
