"""The hosted board's worker (issue #34): clean runs, failures with their reason, killed and paused workers.

The queue's behaviour is tested with a deterministic in-process evaluator of a built-in
policy (the worker's ``evaluator`` parameter), so that a worker killed or paused at any
moment leaves rows that must equal a clean run's; one test runs the real sandbox. Every
test runs on SQLite and on PostgreSQL (the ``postgres_url`` fixture of tests/conftest.py).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import sqlalchemy as sa
from wfbench.leaderboard.board import worker as worker_mod
from wfbench.leaderboard.board.worker import Worker, run_worker
from wfbench.leaderboard.store import ROW_COLUMNS
from wfbench.leaderboard.tracks import scenario_track

from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.harness.guard import PolicyError

ROOT = Path(__file__).resolve().parents[2]
POLICY = "heuristic"  # what the in-process evaluator plays, whatever the package
TINY = scenario_track(name="tiny", config=ScenarioConfig.preset("small").replace(name="tiny", horizon=20),
                      public_seeds=tuple(range(1000, 1006)), test_seeds=(0, 1, 2),
                      description="a tiny track for the tests",
                      references={"tiny": (0.0, 1.0)})  # no published constants: normalized = NSW


def builtin_evaluator(package_dir, entry, config, seeds, limits, key_secret, key_context, chunk_size=None):
    """A deterministic stand-in for the sandbox: the built-in POLICY on ``seeds``, in this process."""
    return evaluate(POLICY, config, list(seeds), execution=Execution(threads=1))


def slow_evaluator(delay):
    def run(*args, **kwargs):
        time.sleep(delay)
        return builtin_evaluator(*args, **kwargs)
    return run


def blob_unpack(data, dest):
    (Path(dest) / "package.bin").write_bytes(data)


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY})


def submit(board, phase="dev", data=b"package bytes"):
    acct = board.account(board.add_account("alice"))
    return board.submit(acct, "tiny", phase, board.put_package(data), "mypkg:Policy", "mine")[0]


def clean_rows(seeds):
    """What a clean run stores: the built-in policy evaluated directly, by seed."""
    rows = evaluate(POLICY, TINY.config, list(seeds), execution=Execution(threads=1))
    return rows.set_index("seed")[list(ROW_COLUMNS)]


def stored(board, sub):
    rows = board.rows(sub.id)
    assert not rows.duplicated(["scenario", "seed_index"]).any()
    return rows


def assert_equals_clean_run(board, sub):
    rows = stored(board, sub).set_index("seed")[list(ROW_COLUMNS)]
    pd.testing.assert_frame_equal(rows, clean_rows(TINY.public_seeds), check_dtype=False, check_exact=True)


def test_a_clean_run_stores_the_rows_of_a_direct_evaluation(board):
    sub = submit(board)
    w = Worker(board, "w1", lease_s=30, chunk_size=4, evaluator=builtin_evaluator, unpack=blob_unpack,
               say=lambda line: None)
    assert w.run_one() == "done" and w.run_one() is None
    s = board.submission(sub.id)
    assert (s.state, s.reason, s.attempts) == ("done", "", 1)
    assert_equals_clean_run(board, sub)
    assert s.result["episodes"] == 6
    assert s.result["kpis"]["nsw"]["mean"] == pytest.approx(clean_rows(TINY.public_seeds)["nsw"].mean())
    rows = board.rows(sub.id)
    assert rows["machine"].str.contains("sandbox x1").all() and np.isfinite(rows["cpu_s"]).all()


def test_a_test_phase_job_runs_on_the_hidden_seeds(board):
    h = board.ensure_hidden_seeds("tiny", n=3)
    sub = submit(board, "test")
    Worker(board, "w", chunk_size=2, evaluator=builtin_evaluator, unpack=blob_unpack, say=lambda line: None).run_one()
    rows = stored(board, sub)
    assert "seed" not in rows and rows["seed_index"].tolist() == [0, 1, 2]
    expected = clean_rows(h.seeds)
    assert rows["nsw"].tolist() == expected["nsw"].tolist(), "row i is the episode of hidden seed i"


class FakeSandboxError(PolicyError):
    """What the sandbox raises (a PolicyError with a one-line reason and the captured log)."""

    def __init__(self, reason, log):
        super().__init__(reason)
        self.reason, self.log = reason, log


def test_a_failing_policy_fails_the_submission_with_its_reason_and_log(board):
    sub = submit(board)
    calls = []

    def evaluator(*args, **kwargs):
        calls.append(args[3])
        if len(calls) == 2:
            raise FakeSandboxError("act took longer than 10 s (the act time limit)", "policy: thinking...\n")
        return builtin_evaluator(*args, **kwargs)

    lines = []
    w = Worker(board, "w", chunk_size=2, evaluator=evaluator, unpack=blob_unpack, say=lines.append)
    assert w.run_one() == "failed"
    s = board.submission(sub.id)
    assert (s.state, s.reason) == ("failed", "act took longer than 10 s (the act time limit)")
    assert s.log == "policy: thinking...\n" and s.result is None
    assert len(stored(board, sub)) == 2, "the chunk before the failure is kept"
    assert f"submission {sub.id} failed: act took longer than 10 s" in "\n".join(lines)


def test_a_package_the_unpacker_refuses_fails_with_its_reason(board):
    sub = submit(board)

    class PackageError(ValueError):
        pass

    def refuse(data, dest):
        raise PackageError("zip-slip: member '../x' would land outside the package")

    Worker(board, "w", evaluator=builtin_evaluator, unpack=refuse, say=lambda line: None).run_one()
    s = board.submission(sub.id)
    assert (s.state, s.reason) == ("failed", "zip-slip: member '../x' would land outside the package")


def test_the_worker_refuses_to_start_without_the_sandbox(board, monkeypatch, capsys):
    from wfbench.harness.isolation.sandbox import SandboxUnavailable

    def missing():
        raise SandboxUnavailable("bubblewrap (bwrap) is not installed: apt-get install bubblewrap")

    monkeypatch.setattr(worker_mod, "check_sandbox", missing)
    submit(board)
    assert run_worker(board.url, once=True, tracks={"tiny": TINY}) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench worker: error: bubblewrap (bwrap) is not installed: apt-get install bubblewrap; "
                          "the worker never runs a submission outside the sandbox")
    assert board.submission(1).state == "queued", "nothing was claimed"


def test_a_bad_database_url_is_one_line(capsys):
    assert run_worker("mysql://x/y", once=True, evaluator=builtin_evaluator) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench worker: error: database 'mysql://x/y' is not allowed; allowed: a file path")
    assert err.count("\n") == 1


# -- workers that die or stall mid-job ----------------------------------------------------------------------

WORKER = """
import sys
from tests.leaderboard.test_worker import TINY, blob_unpack, slow_evaluator
from wfbench.leaderboard.board.worker import run_worker
sys.exit(run_worker(sys.argv[1], worker_id=sys.argv[2], lease_s=float(sys.argv[3]), once=True, poll_s=0.1,
                    chunk_size=1, tracks={"tiny": TINY}, evaluator=slow_evaluator(float(sys.argv[4])),
                    unpack=blob_unpack))
"""


def start_worker(url, name, lease_s, delay):
    return subprocess.Popen([sys.executable, "-c", WORKER, url, name, str(lease_s), str(delay)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_rows(board, sub, n, proc, timeout=60.0):
    deadline = time.monotonic() + timeout
    while len(board.rows(sub.id)) < n:
        assert proc.poll() is None, f"the worker ended early: {proc.communicate()[1]}"
        assert time.monotonic() < deadline, "the worker stored no rows in time"
        time.sleep(0.05)


def finish_with_another_worker(board, timeout=30.0):
    """Run a second worker until it has taken over and finished the job (it waits for the lease to expire)."""
    w = Worker(board, "rescuer", lease_s=30, chunk_size=2, evaluator=builtin_evaluator, unpack=blob_unpack,
               say=lambda line: None)
    deadline = time.monotonic() + timeout
    while (state := w.run_one()) is None:
        assert time.monotonic() < deadline, "the job was never claimed again"
        time.sleep(0.1)
    return state


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_worker_killed_mid_job_is_replaced_and_the_rows_equal_a_clean_run(board, sig):
    sub = submit(board)
    proc = start_worker(board.url, "doomed", 1.0, 0.3)
    wait_for_rows(board, sub, 2, proc)
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=30)
    assert len(board.rows(sub.id)) < len(TINY.public_seeds), "killed mid-job"
    if sig == signal.SIGTERM:
        assert proc.returncode == 143
        assert "stopped by SIGTERM; the job's lease will expire and another worker resumes it" in err
    assert finish_with_another_worker(board) == "done"
    s = board.submission(sub.id)
    assert (s.state, s.attempts) == ("done", 2)
    assert_equals_clean_run(board, sub)


@pytest.mark.slow
def test_a_worker_paused_past_its_lease_cannot_write_when_it_resumes(board):
    sub = submit(board)
    proc = start_worker(board.url, "zombie", 1.0, 0.4)
    wait_for_rows(board, sub, 1, proc)
    os.kill(proc.pid, signal.SIGSTOP)
    try:
        paused_at = len(board.rows(sub.id))
        assert finish_with_another_worker(board) == "done"
    finally:
        os.kill(proc.pid, signal.SIGCONT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert f"submission {sub.id}: worker zombie lost its lease" in err, err
    assert paused_at < len(TINY.public_seeds)
    s = board.submission(sub.id)
    assert (s.state, s.reason, s.attempts) == ("done", "", 2), "the zombie changed nothing"
    assert_equals_clean_run(board, sub)
    with board.engine.begin() as conn:
        assert conn.execute(sa.text("SELECT lease_owner FROM jobs")).scalar() == "rescuer"


# -- the real sandbox ---------------------------------------------------------------------------------------

IDLE = textwrap.dedent("""
    import numpy as np


    class Idle:
        decisions = ("dispatch", "workforce", "positioning")

        def reset(self, keys):
            pass

        def act(self, obs):
            B, M = obs["dispatch_mask"].shape[:2]
            N = obs["dispatch_mask"].shape[2] - 1
            return {"dispatch": np.full((B, M), N), "workforce": np.zeros(B, dtype=np.int64),
                    "positioning": np.ones((B, 2, M))}
""")


@pytest.mark.slow
def test_the_worker_runs_a_package_in_the_real_sandbox(board, bwrap, tmp_path, monkeypatch):
    from wfbench.harness.isolation.package import pack

    (tmp_path / "idlepkg").mkdir()
    (tmp_path / "idlepkg" / "__init__.py").write_text(IDLE)
    data = pack("idlepkg:Idle", root=tmp_path)
    acct = board.account(board.add_account("alice"))
    sub = board.submit(acct, "tiny", "dev", board.put_package(data), "idlepkg:Idle", "idle")[0]
    assert Worker(board, "w", chunk_size=3, say=lambda line: None).run_one() == "done", \
        board.submission(sub.id).reason
    monkeypatch.syspath_prepend(str(tmp_path))
    from idlepkg import Idle

    direct = evaluate(Idle(), TINY.config, list(TINY.public_seeds)).set_index("seed")[list(ROW_COLUMNS)]
    rows = stored(board, sub).set_index("seed")[list(ROW_COLUMNS)]
    pd.testing.assert_frame_equal(rows, direct, check_dtype=False, check_exact=True)
