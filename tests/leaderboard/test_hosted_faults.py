"""Issue #42, the hosted board's outcomes: whose fault a failure is, and what a worker may cost.

- The policy's own failures (raised, timed out, out of memory, bad action) are final;
  the board's (the sandbox did not start, disk full, a lost worker) put the job back in
  the queue, up to :data:`~wfbench.leaderboard.board.db.MAX_ATTEMPTS` claims, and a
  resubmission of the same bytes after such a fault runs again.
- One upload holds a worker for at most its time budget (``job_time_s``, charged across
  attempts); each chunk's wall limit is what is left of it.
- A worker removes the unpack folders a killed worker left.

Every test that touches the database runs on SQLite and PostgreSQL.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import sqlalchemy as sa
from wfbench.leaderboard.board import queue
from wfbench.leaderboard.board.db import MAX_ATTEMPTS, failure_kind
from wfbench.leaderboard.board.worker import Worker, stale_unpack_dirs, unpack_prefix

from tests.leaderboard.test_worker import (
    ROOT,
    TINY,
    assert_equals_clean_run,
    blob_unpack,
    builtin_evaluator,
    submit,
)
from wfbench.harness.guard import PolicyError
from wfbench.harness.isolation.package import PackageError
from wfbench.harness.isolation.sandbox import SandboxError, SandboxUnavailable


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY})


def worker(board, evaluator=builtin_evaluator, name="w", **kw):
    return Worker(board, name, lease_s=30, chunk_size=3, evaluator=evaluator, unpack=blob_unpack,
                  say=lambda line: None, **kw)


def failing_once(exc):
    """An evaluator that raises ``exc`` on its first call and evaluates afterwards."""
    calls = []

    def run(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1:
            raise exc
        return builtin_evaluator(*args, **kwargs)

    return run


def always(exc):
    def run(*args, **kwargs):
        raise exc

    return run


# -- 1. whose fault ---------------------------------------------------------------------------------------------


def test_a_sandbox_that_does_not_start_puts_the_job_back_at_once_and_the_next_worker_runs_it(board):
    sub = submit(board)
    w = worker(board, failing_once(SandboxUnavailable("bwrap: execvp python3: No such file or directory")))
    with pytest.raises(SandboxUnavailable):  # this worker cannot sandbox: it stops (run_worker exits 2)
        w.run_one()
    s = board.submission(sub.id)
    assert (s.state, s.attempts, s.fault, s.kind) == ("queued", 1, "board", "board fault")
    assert "board fault" in s.note and f"attempt 1 of at most {MAX_ATTEMPTS}" in s.note
    assert worker(board, name="w2").run_one() == "done", "queued again at once, not after the lease"
    s = board.submission(sub.id)
    assert (s.state, s.reason, s.fault, s.kind, s.attempts) == ("done", "", "", "", 2)
    assert_equals_clean_run(board, sub)


def test_a_full_disk_puts_the_job_back_and_the_worker_goes_on(board):
    sub = submit(board)
    w = worker(board, failing_once(OSError(errno.ENOSPC, "No space left on device")))
    assert w.run_one() == "requeued"
    assert board.submission(sub.id).state == "queued"
    assert w.run_one() == "done"
    assert_equals_clean_run(board, sub)


def test_board_faults_stop_after_the_attempt_limit_and_a_resubmission_runs_again(board):
    sub = submit(board)
    w = worker(board, always(OSError(errno.ENOSPC, "No space left on device")))
    states = [w.run_one() for _ in range(MAX_ATTEMPTS)]
    assert states == ["requeued"] * (MAX_ATTEMPTS - 1) + ["failed"]
    assert w.run_one() is None, "nothing left in the queue"
    s = board.submission(sub.id)
    assert (s.state, s.fault, s.kind, s.attempts) == ("failed", "board", "board fault", MAX_ATTEMPTS)
    assert s.reason.startswith(f"board fault {MAX_ATTEMPTS} times: ") and "No space left on device" in s.reason
    again, created = board.submit(board.account_by_name("alice"), "tiny", "dev", s.package_sha, s.entry, s.name)
    assert created and again.id == sub.id and again.state == "queued" and again.attempts == 0
    assert worker(board).run_one() == "done"
    assert_equals_clean_run(board, sub)


def test_a_lost_worker_is_the_boards_fault_too(board):
    sub = submit(board)
    for i in range(MAX_ATTEMPTS):
        assert queue.claim(board.engine, f"dies{i}", 0.05) is not None
        time.sleep(0.1)
    assert queue.claim(board.engine, "late", 30) is None
    s = board.submission(sub.id)
    assert (s.state, s.fault, s.kind) == ("failed", "board", "board fault")
    assert board.submit(board.account_by_name("alice"), "tiny", "dev", s.package_sha, s.entry, s.name)[1]


@pytest.mark.parametrize(("reason", "kind"), [
    ("the policy raised KeyError: 'x' in act at pol.py:3", "raised"),
    ("act took longer than 10 s (the act time limit)", "timed out"),
    ("the policy took longer than 1800 s over one batch of episodes (the wall time limit)", "timed out"),
    ("MemoryError: cannot allocate in act at pol.py:9 (memory limit 4096 MB)", "out of memory"),
    ("the policy's process ended with signal 9 (SIGKILL: memory limit 4096 MB?) during act", "out of memory"),
    ("the policy returned a malformed action at step 3: ActionError: dispatch has shape (1, 2)", "bad action"),
])
def test_the_policys_own_failures_are_final_with_their_kind(board, reason, kind):
    sub = submit(board)
    assert worker(board, always(SandboxError(reason))).run_one() == "failed"
    s = board.submission(sub.id)
    assert (s.state, s.reason, s.fault, s.kind) == ("failed", reason, "policy", kind)
    again, created = board.submit(board.account_by_name("alice"), "tiny", "dev", s.package_sha, s.entry, s.name)
    assert not created and again.state == "failed", "the same bytes would fail the same way: not run again"
    assert worker(board).run_one() is None


def test_failure_kinds_are_a_fixed_vocabulary():
    assert failure_kind(PolicyError("did not return from act within the act timeout of 10 s")) == "timed out"
    assert failure_kind(PackageError("zip-slip: member '../x'")) == "package refused"
    assert failure_kind(ValueError("zip-slip: member '../x'")) == "raised"
    assert failure_kind(SandboxError("anything at all the policy wrote " * 20)) == "raised"


# -- 3. the bound per upload --------------------------------------------------------------------------------------


def test_one_upload_holds_a_worker_for_at_most_its_time_budget_across_attempts(board):
    sub = submit(board)
    walls = []

    def slow(package_dir, entry, config, seeds, limits, *args, **kwargs):
        walls.append(limits.wall_time_s)
        time.sleep(0.4)
        return builtin_evaluator(package_dir, entry, config, seeds, limits, *args, **kwargs)

    w = Worker(board, "w", lease_s=30, chunk_size=1, evaluator=slow, unpack=blob_unpack, say=lambda line: None,
               job_time_s=1.0)
    start = time.monotonic()
    assert w.run_one() == "failed"
    assert time.monotonic() - start < 3.0
    s = board.submission(sub.id)
    assert (s.fault, s.kind) == ("policy", "timed out")
    assert s.reason.startswith("used its time budget of 1 s of worker time per upload")
    assert 0.8 < walls[0] <= 1.0 and walls == sorted(walls, reverse=True), "each chunk gets what is left"
    assert len(walls) <= 3 and s.spent_s >= 1.0
    stored = len(board.rows(sub.id))
    assert 1 <= stored < len(TINY.public_seeds)


def test_the_time_spent_on_an_upload_is_kept_when_its_worker_is_lost(board):
    sub = submit(board)
    c = queue.claim(board.engine, "doomed", 30)
    assert queue.heartbeat(c, spent_s=0.75)
    assert board.submission(sub.id).spent_s == pytest.approx(0.75)
    walls = []

    def record(package_dir, entry, config, seeds, limits, *args, **kwargs):
        walls.append(limits.wall_time_s)
        return builtin_evaluator(package_dir, entry, config, seeds, limits, *args, **kwargs)

    with board.engine.begin() as conn:  # the lease runs out
        conn.execute(sa.text("UPDATE jobs SET lease_until = 0"))
    assert worker(board, record, job_time_s=100.0).run_one() == "done"
    assert walls[0] <= 100.0 - 0.75
    assert board.submission(sub.id).spent_s >= 0.75


# -- 6. what a killed worker leaves -------------------------------------------------------------------------------

SLOW_WORKER = """
import sys
from tests.leaderboard.test_worker import TINY, blob_unpack, slow_evaluator
from wfbench.leaderboard.board.worker import run_worker
sys.exit(run_worker(sys.argv[1], worker_id="doomed", lease_s=30, once=True, poll_s=0.1, chunk_size=1,
                    tracks={"tiny": TINY}, evaluator=slow_evaluator(5.0), unpack=blob_unpack))
"""


@pytest.mark.slow
def test_a_worker_removes_the_unpack_folders_a_killed_worker_left(board, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    submit(board)
    proc = subprocess.Popen([sys.executable, "-c", SLOW_WORKER, board.url], cwd=ROOT, env={**os.environ,
                            "TMPDIR": str(work)}, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not list(work.glob("wfbench-worker-*/policy/package.bin")):
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, "the worker never unpacked its package"
        time.sleep(0.05)
    (left,) = list(work.glob("wfbench-worker-*"))
    live_w = worker(board, name="alive", work_dir=work)
    assert stale_unpack_dirs(work) == [], "the owner is alive: its folder is not stale"
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    assert left.is_dir(), "SIGKILL leaves the unpacked package behind"
    assert stale_unpack_dirs(work) == [left]
    mine = Path(tempfile.mkdtemp(prefix=unpack_prefix(), dir=work))  # this (live) process's own stays
    other = work / "wfbench-workerish"  # not a worker's folder
    other.mkdir()
    live_w.run(once=True)
    assert not left.exists(), "removed on the next worker's start"
    assert other.is_dir() and mine.is_dir()
