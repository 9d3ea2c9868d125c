"""The hosted board's job queue (issue #34): leases, fencing, attempts, and concurrent claimers never sharing a job.

Every test runs on SQLite and on PostgreSQL (the ``postgres_url`` fixture of tests/conftest.py).
"""

from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import pytest
import sqlalchemy as sa
from wfbench.leaderboard.board import queue
from wfbench.leaderboard.board.queue import LeaseLost, claim, finish, heartbeat, write_rows

from tests.leaderboard.test_hosted_db import TINY, fake_rows

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY}, dev_concurrent=100, dev_daily_quota=100)  # the queue, not the quota


def queued(board, n=1):
    """``n`` queued dev-phase submissions of one account."""
    acct = board.account(board.add_account("alice"))
    return [board.submit(acct, "tiny", "dev", board.put_package(f"pkg{i}".encode()), "p:P", f"s{i}")[0]
            for i in range(n)]


def job(board, sub_id):
    with board.engine.begin() as conn:
        return conn.execute(sa.text("SELECT * FROM jobs WHERE submission_id = :i"), {"i": sub_id}).mappings().one()


def count_rows(board, sub_id):
    with board.engine.begin() as conn:
        return conn.execute(sa.text("SELECT count(*) FROM rows WHERE submission_id = :i"), {"i": sub_id}).scalar()


def test_claim_takes_the_oldest_queued_job_with_a_lease_and_a_fence(board):
    assert claim(board.engine, "w1", 30) is None, "an empty queue"
    first, second = queued(board, 2)
    c = claim(board.engine, "w1", 30)
    assert (c.submission_id, c.fence, c.attempt, c.worker_id) == (first.id, 1, 1, "w1")
    j = job(board, first.id)
    assert j["state"] == "running" and j["lease_owner"] == "w1" and j["lease_until"] > time.time() + 25
    assert board.submission(first.id).state == "running" and board.submission(first.id).attempts == 1
    assert claim(board.engine, "w2", 30).submission_id == second.id, "a held job is not claimed again"
    assert claim(board.engine, "w3", 30) is None


def test_a_paused_worker_cannot_write_after_another_took_its_job(board):
    (sub,) = queued(board)
    units = board.units(sub)
    old = claim(board.engine, "old", 0.3)
    assert write_rows(old, fake_rows(units[:1], 0.5)) == 1
    time.sleep(0.5)  # the lease runs out: the old worker stalls
    new = claim(board.engine, "new", 30)
    assert (new.submission_id, new.fence, new.attempt) == (sub.id, 2, 2)
    assert not heartbeat(old), "the old worker's heartbeat is refused"
    with pytest.raises(LeaseLost, match=f"submission {sub.id}: worker old lost its lease \\(fence 1 is stale"):
        write_rows(old, fake_rows(units, 0.5))
    with pytest.raises(LeaseLost):
        finish(old, "failed", "too late")
    assert count_rows(board, sub.id) == 1, "the refused write stored nothing; the first holder's row stays"
    done = board.done_units(sub.id)
    assert write_rows(new, fake_rows([u for u in units if u[:2] not in done], 0.5)) == len(units) - 1
    finish(new, "done", "", {"ok": 1})
    s = board.submission(sub.id)
    assert (s.state, s.reason, s.result, count_rows(board, sub.id)) == ("done", "", {"ok": 1}, len(units))


@pytest.mark.slow
def test_heartbeats_keep_the_lease(board):
    queued(board)
    c = claim(board.engine, "w", 3.0)  # seconds of slack: a loaded machine may sleep late
    for _ in range(4):
        time.sleep(1.0)  # four heartbeats span longer than the lease itself
        assert heartbeat(c)
    assert claim(board.engine, "thief", 30) is None, "a renewed lease is not expired"
    assert job(board, c.submission_id)["lease_until"] > time.time() + 1.0


def test_a_job_whose_worker_stopped_answering_shows_as_queued_with_a_note_not_running(board):
    """The commonest complaint about hosted boards: a job "running" for days. A lost lease is said at once."""
    (sub,) = queued(board)
    claim(board.engine, "w1", 1.0)
    assert (board.submission(sub.id).state, board.submission(sub.id).note) == ("running", "")
    time.sleep(1.2)
    shown = board.submission(sub.id)
    assert shown.state == "queued" and shown.reason == ""
    assert shown.note.startswith("its worker w1 stopped answering (lease ended ")
    assert shown.note.endswith("); the next worker resumes it with the episodes still missing (attempt 2 of at most 3)")
    claim(board.engine, "w2", 30)
    assert (board.submission(sub.id).state, board.submission(sub.id).note) == ("running", "")


def test_a_job_that_loses_its_worker_three_times_fails_with_the_reason(board):
    (sub,) = queued(board)
    for attempt in (1, 2, 3):
        c = claim(board.engine, f"w{attempt}", 0.05)
        assert c.attempt == attempt
        time.sleep(0.1)
    assert claim(board.engine, "w4", 30) is None
    s = board.submission(sub.id)
    assert s.state == "failed" and s.attempts == 3
    assert s.reason == ("lost its worker 3 times (the worker died or stalled past its lease each time); submit the "
                        "same package again to queue it again")
    assert job(board, sub.id)["state"] == "failed"


def test_a_job_lost_by_its_workers_is_queued_again_when_submitted_again_and_keeps_its_rows(board):
    alice = board.account(board.add_account("alice"))
    sub, _ = board.submit(alice, "tiny", "dev", board.put_package(b"pkg"), "p:P", "s")
    c = claim(board.engine, "w1", 30)
    write_rows(c, fake_rows(board.units(sub)[:1], 0.5))  # one unit stored before the workers were lost
    with board.engine.begin() as conn:  # as after three lost leases (the test above)
        conn.execute(sa.text("UPDATE jobs SET lease_until = 0"))
        conn.execute(sa.text("UPDATE submissions SET attempts = 3"))
    assert claim(board.engine, "w4", 30) is None and board.submission(sub.id).state == "failed"
    again, created = board.submit(alice, "tiny", "dev", sub.package_sha, sub.entry, sub.name)
    assert created and again.id == sub.id and (again.state, again.reason, again.attempts) == ("queued", "", 0)
    c = claim(board.engine, "w5", 30)
    assert c.submission_id == sub.id and c.attempt == 1 and c.fence > 1  # the old holders stay fenced out
    assert count_rows(board, sub.id) == 1, "the rows stored before are kept"
    # a policy's own failure is not queued again: the same bytes would fail the same way
    finish(c, "failed", "the policy raised ValueError")
    assert board.submit(alice, "tiny", "dev", sub.package_sha, sub.entry, sub.name)[1] is False



def test_rows_are_checked_and_stored_once(board):
    (sub,) = queued(board)
    c = claim(board.engine, "w", 30)
    units = board.units(sub)
    assert write_rows(c, fake_rows(units[:2], 0.5)) == 2
    nan_budget = fake_rows(units, 0.5)
    nan_budget[2]["cpu_s"] = math.nan
    assert write_rows(c, nan_budget) == 1, "units already stored are skipped"
    assert write_rows(c, fake_rows(units, 0.5)) == 0
    bad = fake_rows(units[:1], 0.5)
    bad[0]["nsw"] = math.nan
    with pytest.raises(ValueError, match=r"scenario '', seed index 0: non-finite nsw \(nan\); no row was stored"):
        write_rows(c, bad)
    rows = board.rows(sub.id)
    assert rows["seed_index"].tolist() == [0, 1, 2] and rows["nsw"].tolist() == [0.5, 0.51, 0.52]
    assert rows["cpu_s"].tolist()[:2] == [0.01, 0.01] and math.isnan(rows["cpu_s"].iloc[2]), "NaN stored as NULL"
    finish(c, "failed", "the policy raised\nValueError: two lines")
    assert board.submission(sub.id).reason == "the policy raised ValueError: two lines", "one line"
    with pytest.raises(ValueError, match="final state 'queued' is not allowed; allowed: done, failed"):
        finish(c, "queued")


def test_concurrent_claimers_in_threads_never_share_a_job(board):
    subs = queued(board, 12)
    claimed: list[tuple[str, int]] = []
    errors: list[BaseException] = []

    def work(name):
        try:
            while (c := claim(board.engine, name, 30)) is not None:
                claimed.append((name, c.submission_id))
                finish(c, "done", "", {})
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(f"t{i}",)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert sorted(i for _, i in claimed) == [s.id for s in subs], "every job claimed exactly once"
    assert all(board.submission(s.id).state == "done" for s in subs)


CLAIMER = """
import sys, time
from pathlib import Path
from wfbench.leaderboard.board.db import Board
from wfbench.leaderboard.board.queue import claim, finish
board = Board(sys.argv[1], tracks={})
ready, name, n = Path(sys.argv[2]), sys.argv[3], int(sys.argv[4])
(ready / name).touch()
deadline = time.monotonic() + 60
while len(list(ready.iterdir())) < n and time.monotonic() < deadline:  # every process claims from the same moment
    time.sleep(0.01)
while (c := claim(board.engine, name, 30)) is not None:
    print(c.submission_id, flush=True)
    time.sleep(0.01)
    finish(c, "done", "", {})
"""


@pytest.mark.slow
def test_concurrent_claimers_in_processes_never_share_a_job(board, tmp_path):
    subs = queued(board, 30)
    ready = tmp_path / "ready"
    ready.mkdir()
    procs = [subprocess.Popen([sys.executable, "-c", CLAIMER, board.url, str(ready), f"p{i}", "3"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(3)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err for _, err in outs]
    got = Counter(int(line) for out, _ in outs for line in out.split())
    assert sorted(got) == [s.id for s in subs] and set(got.values()) == {1}, "every job claimed exactly once"
    assert sum(1 for out, _ in outs if out.strip()) >= 2, "the processes did claim side by side"
    assert all(board.submission(s.id).state == "done" for s in subs)


def test_lease_must_be_positive(board):
    with pytest.raises(ValueError, match="lease 0 s is not allowed; allowed: seconds > 0"):
        queue.claim(board.engine, "w", 0)


def test_a_claim_of_one_submission_takes_its_job_only_and_write_rows_calls_then_with_the_new_rows(board):
    older, mine = queued(board, 2)
    assert claim(board.engine, "local", 30, submission_id=4242) is None, "no such job"
    c = claim(board.engine, "local", 30, submission_id=mine.id)
    assert c.submission_id == mine.id and job(board, older.id)["state"] == "queued", "the older job is left queued"
    units = board.units(board.submission(mine.id))
    seen = []
    assert write_rows(c, fake_rows(units[:2], 0.5), then=lambda conn, rows: seen.extend(rows)) == 2
    assert [r["seed_index"] for r in seen] == [u[1] for u in units[:2]]
    seen.clear()
    assert write_rows(c, fake_rows(units[:3], 0.5), then=lambda conn, rows: seen.extend(rows)) == 1
    assert [r["seed_index"] for r in seen] == [units[2][1]], "a unit already stored is not passed on"
