"""Issue #42, the hosted board's accounts: dedupe per account (the built-ins cannot be squatted), a database made
before that change, the development phase's quota, and an owner listing and withdrawing their submissions.

Every test that touches the database runs on SQLite and PostgreSQL.
"""

from __future__ import annotations

import time

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from wfbench.leaderboard.board import queue
from wfbench.leaderboard.board.db import (
    PROVENANCE_COLUMNS,
    Board,
    BoardError,
    QuotaExceeded,
    accounts,
    hidden_seeds,
    jobs,
    packages,
    rows,
    secrets_table,
)
from wfbench.leaderboard.board.seed import ACCOUNT, builtin_package, seed
from wfbench.leaderboard.server.app import create_app

from tests.leaderboard.test_hosted_db import TINY, fake_rows, run_fake
from tests.leaderboard.test_server import TRACK, make_package, post, run_jobs, serve_board
from wfbench.cli import main


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY})


# -- 2. built-ins belong to the board -------------------------------------------------------------------------


def test_uploads_are_deduplicated_per_account(board):
    alice, bob = (board.account(board.add_account(n)) for n in ("alice", "bob"))
    sha = board.put_package(b"pkg")
    first, created = board.submit(alice, "tiny", "dev", sha, "mypkg:Policy", "mine")
    assert created
    again, created = board.submit(alice, "tiny", "dev", sha, "mypkg:Policy", "another name")
    assert not created and again.id == first.id and again.name == "mine"
    theirs, created = board.submit(bob, "tiny", "dev", sha, "mypkg:Policy", "bobs")
    assert created and theirs.id != first.id and (theirs.account, theirs.name) == ("bob", "bobs")
    assert first.account == "alice" and board.submission(first.id).name == "mine"


def test_another_accounts_copy_of_a_builtin_does_not_squat_it(board):
    mallory = board.account(board.add_account("mallory"))
    copy, _ = board.submit(mallory, "tiny", "dev", board.put_package(builtin_package("heuristic")),
                           "wfbench_builtin:policy", "my-heuristic")
    (made,) = seed(board, phases=("dev",), names=("heuristic",))
    assert made.created and made.submission_id != copy.id, made.line()
    assert made.line() == f"heuristic on tiny (dev): submission {made.submission_id} queued"
    own = board.submission(made.submission_id)
    assert (own.account, own.name) == (ACCOUNT, "heuristic")
    assert (board.submission(copy.id).account, board.submission(copy.id).name) == ("mallory", "my-heuristic")
    run_fake(board, copy, 0.9)
    run_fake(board, own, 0.4)
    names = {s.name for s in board.entries("tiny", "dev")}
    assert names == {"heuristic", "my-heuristic"}


# A board made before issue #42: the submissions table as it was (dedupe on the package alone), the others as now.
V1 = sa.MetaData()
V1_SUBMISSIONS = sa.Table(
    "submissions", V1,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("account_id", sa.Integer, sa.ForeignKey("accounts.id"), nullable=False),
    sa.Column("track", sa.String(100), nullable=False),
    sa.Column("track_hash", sa.String(64), nullable=False),
    sa.Column("phase", sa.String(8), nullable=False),
    sa.Column("package_sha", sa.String(71), sa.ForeignKey("packages.sha256"), nullable=False),
    sa.Column("entry", sa.String(300), nullable=False),
    sa.Column("name", sa.String(100), nullable=False),
    sa.Column("state", sa.String(8), nullable=False),
    sa.Column("reason", sa.Text, nullable=False, default=""),
    sa.Column("created", sa.Double, nullable=False),
    sa.Column("updated", sa.Double, nullable=False),
    sa.Column("attempts", sa.Integer, nullable=False, default=0),
    sa.Column("hidden_version", sa.Integer, nullable=True),
    sa.Column("log", sa.Text, nullable=False, default=""),
    sa.Column("result", sa.Text, nullable=True),
    sa.CheckConstraint("phase IN ('dev', 'test')", name="phase_known"),
    sa.CheckConstraint("state IN ('queued', 'running', 'done', 'failed')", name="state_known"),
    sa.UniqueConstraint("package_sha", "entry", "track", "phase", name="same_package_once"),
)
sa.Index("submissions_account", V1_SUBMISSIONS.c.account_id, V1_SUBMISSIONS.c.phase, V1_SUBMISSIONS.c.created)
for table in (accounts, packages, hidden_seeds, secrets_table, jobs):
    table.to_metadata(V1)
# rows as the first schema had them: without the local board's provenance (revision 0003)
sa.Table("rows", V1, *(sa.Column(c.name, c.type, *([sa.ForeignKey("submissions.id")] if c.foreign_keys else []),
                                 nullable=c.nullable) for c in rows.columns if c.name not in PROVENANCE_COLUMNS),
         sa.UniqueConstraint("submission_id", "scenario", "seed_index", name="one_row_per_unit"))


def test_a_board_made_before_per_account_dedupe_is_migrated_in_place(db_url):
    old = Board(db_url, tracks={"tiny": TINY})
    V1.create_all(old.engine)
    now = time.time()
    with old.engine.begin() as conn:
        conn.execute(accounts.insert().values(name="alice", token_hash="a" * 64, admin=False, created=now))
        conn.execute(packages.insert().values(sha256="sha256:aa", bytes=b"x", size=1, created=now))
        base = dict(account_id=1, track="tiny", track_hash=TINY.hash, phase="dev", package_sha="sha256:aa",
                    created=now, updated=now, attempts=1, log="")
        conn.execute(V1_SUBMISSIONS.insert().values(entry="p:A", name="a", state="done", reason="", **base))
        conn.execute(V1_SUBMISSIONS.insert().values(entry="p:B", name="b", state="failed", **base,
                                                    reason="lost its worker 3 times (the worker died)"))
        conn.execute(V1_SUBMISSIONS.insert().values(entry="p:C", name="c", state="failed", **base,
                                                    reason="act took longer than 10 s (the act time limit)"))
        for i in (1, 2, 3):
            conn.execute(jobs.insert().values(submission_id=i, state="done", fence=1))
        conn.execute(rows.insert(), [{"submission_id": 1, **{k: v for k, v in r.items() if k != "machine"},
                                      "finished": now} for r in fake_rows(old.units(_Sub()), 0.5)])
    old.close()  # (ids from each table's own sequence: 1 for alice, 1-3 for the submissions)

    board = Board(db_url, tracks={"tiny": TINY})
    board.create()  # the migration
    board.create()  # twice is harmless
    assert [s.id for s in board.submissions()] == [1, 2, 3] and len(board.rows(1)) == 3
    lost, slow = board.submission(2), board.submission(3)
    assert (lost.fault, lost.kind) == ("board", "board fault") and (slow.fault, slow.kind) == ("policy", "timed out")
    alice = board.account_by_name("alice")
    bob = board.account(board.add_account("bob"))
    theirs, created = board.submit(bob, "tiny", "dev", "sha256:aa", "p:A", "bobs")
    assert created and theirs.id == 4, "the old board's dedupe key (without the account) is gone"
    assert not board.submit(alice, "tiny", "dev", "sha256:aa", "p:A", "a")[1]
    with pytest.raises(sa.exc.IntegrityError):  # the foreign keys still hold after the rebuild
        with board.engine.begin() as conn:
            conn.execute(jobs.insert().values(submission_id=99, state="queued", fence=0))
    board.close()


class _Sub:
    track, phase, track_hash, hidden_version = "tiny", "dev", TINY.hash, None


# -- 3. the development phase's quota ---------------------------------------------------------------------------


def test_the_dev_phase_has_a_per_account_quota(open_board):
    board = open_board({"tiny": TINY}, dev_daily_quota=3, dev_concurrent=2)
    alice, bob = (board.account(board.add_account(n)) for n in ("alice", "bob"))
    shas = [board.put_package(bytes([i])) for i in range(4)]
    first, _ = board.submit(alice, "tiny", "dev", shas[0], "p:P", "one")
    second, _ = board.submit(alice, "tiny", "dev", shas[1], "p:P", "two")
    with pytest.raises(QuotaExceeded) as e:
        board.submit(alice, "tiny", "dev", shas[2], "p:P", "three")
    assert e.value.reason == (f"at most 2 dev-phase jobs queued or running at a time per account: submissions "
                              f"{first.id}, {second.id} are still queued; submit again once one is done or failed")
    assert board.submit(alice, "tiny", "dev", shas[0], "p:P", "one")[1] is False, "a dedupe hit is never refused"
    bobs, created = board.submit(bob, "tiny", "dev", shas[2], "p:P", "b")
    assert created, "another account has its own quota"
    run_fake(board, first, 0.5)
    run_fake(board, second, 0.5)
    run_fake(board, bobs, 0.5)
    third, _ = board.submit(alice, "tiny", "dev", shas[2], "p:P", "three")
    run_fake(board, third, 0.5)
    with pytest.raises(QuotaExceeded) as e:
        board.submit(alice, "tiny", "dev", shas[3], "p:P", "four")
    assert e.value.reason.startswith("daily quota reached: 3 dev-phase submissions in the last 24 h (allowed: 3); "
                                     "the next one is allowed in 14")
    assert " min (at 20" in e.value.reason and e.value.reason.endswith(" UTC)") and "\n" not in e.value.reason
    with pytest.raises(BoardError, match=r"^dev-phase quota 0 is not allowed; allowed: 1 or more$"):
        Board(board.url, tracks={"tiny": TINY}, dev_daily_quota=0)


# -- 4. an owner's list and withdrawal --------------------------------------------------------------------------


def test_an_owner_lists_their_submissions_and_withdraws_one(tmp_path):
    board = Board(tmp_path / "b.sqlite", tracks={TRACK.name: TRACK})
    board.create()
    alice, bob = board.add_account("alice"), board.add_account("bob")
    with TestClient(create_app(board)) as client:
        a1 = post(client, alice, make_package("a1")).json()["id"]
        a2 = post(client, alice, make_package("a2")).json()["id"]
        b1 = post(client, bob, make_package("b1")).json()["id"]
        run_jobs(board, limit=1)  # a1 is done, a2 queued
        mine = client.get("/api/submissions", headers={"Authorization": f"Bearer {alice}"})
        assert mine.status_code == 200
        listed = mine.json()["submissions"]
        assert [(s["id"], s["state"]) for s in listed] == [(a1, "done"), (a2, "queued")]
        assert {"name", "track", "phase", "reason", "url", "created"} <= set(listed[0])
        assert client.get("/api/submissions").status_code == 401
        # withdraw a queued one: its job is cancelled, nothing claims it
        gone = client.delete(f"/api/submissions/{a2}", headers={"Authorization": f"Bearer {alice}"})
        assert gone.status_code == 200 and gone.json()["state"] == "withdrawn"
        assert queue.claim(board.engine, "w", 30).submission_id == b1, "a2's job is cancelled"
        # withdraw a done one: it leaves the board
        names = [e["name"] for e in client.get(f"/api/board/{TRACK.name}").json()["entries"]]
        assert "pol:Policy #1" in names or "pol:Policy" in names
        assert client.delete(f"/api/submissions/{a1}", headers={"Authorization": f"Bearer {alice}"}).status_code \
            == 200
        entries = client.get(f"/api/board/{TRACK.name}").json()["entries"]
        assert a1 not in [e.get("submission_id") for e in entries] and all(e["submitter"] != "alice"
                                                                            for e in entries)
        other = client.delete(f"/api/submissions/{b1}", headers={"Authorization": f"Bearer {alice}"})
        assert other.status_code == 403
        assert other.json()["detail"] == (f"submission {b1} is not yours; allowed: withdrawing your own submissions "
                                          "(GET /api/submissions lists them)")
        assert client.delete("/api/submissions/999", headers={"Authorization": f"Bearer {alice}"}).json() == \
            {"detail": "no submission 999"}
        assert client.get(f"/api/submissions/{a2}").json()["state"] == "withdrawn"
        # the same bytes again: back on the board, run again
        back = post(client, alice, make_package("a2"))
        assert back.status_code == 201 and back.json()["id"] == a2 and back.json()["state"] == "queued"
    board.close()


def test_a_worker_running_a_withdrawn_submission_cannot_write(board):
    alice = board.account(board.add_account("alice"))
    sub, _ = board.submit(alice, "tiny", "dev", board.put_package(b"x"), "p:P", "x")
    c = queue.claim(board.engine, "w", 30)
    board.withdraw(alice, sub.id)
    with pytest.raises(queue.LeaseLost):
        queue.write_rows(c, fake_rows(board.units(sub), 0.5))
    assert len(board.rows(sub.id)) == 0 and board.submission(sub.id).state == "withdrawn"
    assert board.entries("tiny", "dev") == []


def test_every_token_the_board_makes_is_read_by_the_command_line_as_a_value(tmp_path, capsys, monkeypatch):
    # CI once drew a token starting with '-', and argparse took it for an option: "--token: expected one argument"
    import wfbench.leaderboard.board.db as board_db
    monkeypatch.setattr(board_db._secrets, "token_urlsafe", lambda n: "-lWugj0rt4U1TQcN8ZpGMTVAg8fw8ah2iPN2yZkGRvk")
    with serve_board(tmp_path / "board.sqlite") as live:
        assert live.token == "wfb_-lWugj0rt4U1TQcN8ZpGMTVAg8fw8ah2iPN2yZkGRvk"
        assert main(["leaderboard", "mine", "--server", live.url, "--token", live.token]) == 0
        assert capsys.readouterr().err == ""


def test_cli_mine_and_withdraw(tmp_path, capsys):
    with serve_board(tmp_path / "board.sqlite") as live:
        with TestClient(create_app(live.board)) as client:
            first = post(client, live.token, make_package("m1"), name="first").json()["id"]
            post(client, live.token, make_package("m2"), name="second")
        common = ["--server", live.url, "--token", live.token]
        assert main(["leaderboard", "mine", *common]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out[0].split() == ["id", "track", "phase", "state", "name", "reason"]
        assert out[1].split()[:5] == [str(first), TRACK.name, "dev", "queued", "first"]
        assert len(out) == 3
        assert main(["leaderboard", "withdraw", *common, "--id", str(first)]) == 0
        assert capsys.readouterr().out == (f"withdrew submission {first} (first on {TRACK.name}, dev phase): it is "
                                           "off the board and its queued job is cancelled\n")
        assert main(["leaderboard", "withdraw", *common, "--id", "77"]) == 1
        assert capsys.readouterr().err == "wfbench: error: withdrawing submission 77 refused by the server (404): " \
                                          "no submission 77\n"
        assert main(["leaderboard", "withdraw", "--server", live.url, "--token", live.token]) == 2
        assert "--id is needed with --server" in capsys.readouterr().err
        assert main(["leaderboard", "withdraw"]) == 2
        assert capsys.readouterr().err == ("wfbench: error: withdraw takes --name (an entry of the local store) or "
                                           "--server and --id (a hosted submission)\n")


def test_cli_serve_end_test(tmp_path, capsys):
    db = str(tmp_path / "board.sqlite")
    assert main(["serve", "end-test", "paper-64", "--db", db]) == 0
    out = capsys.readouterr().out
    assert out.startswith("the test phase of track paper-64 ended at 20") and out.endswith(
        "UTC: no test submission is taken any more, and its failures' whole reasons are shown\n")
    board = Board(db)
    assert board.test_phase_ended("paper-64") is not None and board.test_phase_ended("large") is None
    board.close()
    assert main(["serve", "end-test", "nowhere", "--db", db]) == 2
    assert capsys.readouterr().err.startswith("wfbench: error: unknown track 'nowhere'; available: paper-64")
