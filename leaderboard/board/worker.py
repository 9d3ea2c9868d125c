"""``wfbench worker --server DBURL``: evaluate queued submissions and store their rows, fenced.

The loop: :func:`~wfbench.leaderboard.board.queue.claim` a job, ask the :class:`Runner` for its
missing units chunk by chunk, store each chunk (:func:`~wfbench.leaderboard.board.queue.write_rows`)
and finish, a thread renewing the lease. The hosted board's runner (:class:`SandboxRunner`)
unpacks the package and runs each chunk in the sandbox; the local board runs the same worker with
its own (``wfbench.leaderboard.local``). The policy's failures are final; the board's hand the job
back. :func:`warm_builtins` warms the sandboxes' numba cache; :func:`stale_unpack_dirs` finds
folders of killed workers. ``docs/leaderboard.md``, "The hosted leaderboard" and "One board".
"""

from __future__ import annotations

import dataclasses
import errno
import math
import os
import re
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, Protocol

import pandas as pd
import sqlalchemy as sa
from wfbench.leaderboard.board import hidden
from wfbench.leaderboard.board.db import Board, BoardError, Submission, failure_kind
from wfbench.leaderboard.board.queue import (
    DEFAULT_LEASE_S,
    Claim,
    LeaseLost,
    claim,
    finish,
    heartbeat,
    release,
    write_rows,
)
from wfbench.leaderboard.rows import KPI_COLUMNS, ROW_COLUMNS

from wfbench.core.config import ScenarioConfig
from wfbench.harness.budget import BUDGET_COLUMNS, machine, machine_line
from wfbench.harness.evaluation import summarize
from wfbench.harness.guard import PolicyError, one_line

DEFAULT_CHUNK = 5  # seeds per evaluator call and per stored transaction
JOB_TIME_S = 3600.0  # worker seconds one upload may use, per scenario of its track, over every attempt
UNPACK_PREFIX = "wfbench-worker-"
_UNPACK_DIR = re.compile(r"^wfbench-worker-(\d+)-(\d+)-")
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)
Evaluator = Callable[..., pd.DataFrame]
"""``(package_dir, entry, config, seeds, limits, key_secret, key_context, chunk_size=None) -> rows``."""
Unpacker = Callable[[bytes, Path], Any]


@cache
def warm_builtins() -> None:
    """Compile the kernels of the leaderboard's built-ins into this process's numba cache, once per process.

    The sandboxes copy from that cache (:class:`wfbench.harness.isolation.child.CacheCopies`):
    the seeded built-ins (:mod:`wfbench.leaderboard.board.seed`) and any package wrapping
    one then start warm. The shapes do not matter (numba compiles per type), so the
    small preset serves every track. A built-in that reads the trace is skipped: the
    sandbox refuses it.
    """
    from wfbench.policies import registry

    from wfbench.harness.isolation.sandbox import warm_cache

    for name in registry.LINEUPS["leaderboard"]:
        try:
            policy = registry.get(name)
            if not getattr(policy, "reads_trace", False):
                warm_cache(policy, ScenarioConfig.preset("small"))
        except Exception as exc:  # noqa: BLE001 - a cold start for that one's sandboxes, not a dead worker
            print(f"wfbench worker: cannot warm the numba cache for {name!r}: {one_line(exc)}; its sandboxes "
                  "compile it", file=sys.stderr, flush=True)


def sandbox_evaluator(package_dir: str | Path, entry: str, config: ScenarioConfig, seeds: Sequence[int],
                      limits: Any, key_secret: bytes, key_context: str, chunk_size: int | None = None) -> pd.DataFrame:
    """The production evaluator: :func:`wfbench.harness.isolation.sandbox.evaluate_sandboxed` (default limits if None).

    The first call of a process warms its numba cache first (:func:`warm_builtins`).
    """
    from wfbench.harness.isolation import sandbox

    warm_builtins()
    return sandbox.evaluate_sandboxed(package_dir, entry, config, seeds, limits or sandbox.Limits(), key_secret,
                                      key_context, chunk_size=chunk_size)


def package_unpacker(data: bytes, dest: Path) -> Any:
    """The production unpacker: :func:`~wfbench.harness.isolation.package.unpack` (re-checks what it writes)."""
    from wfbench.harness.isolation.package import unpack

    return unpack(data, dest)


def check_sandbox() -> None:
    """Raise :class:`~wfbench.harness.isolation.sandbox.SandboxUnavailable` (saying how to install it) without bwrap."""
    from wfbench.harness.isolation import sandbox

    sandbox.check_sandbox()


def _start_time(pid: int) -> int | None:
    """The start time of process ``pid`` (clock ticks since boot, /proc), 0 where /proc has none; None: no process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return None
    except OSError:
        stat = ""
    if not stat:  # no /proc (not Linux): whether the pid exists at all
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:
            pass
        return 0
    return int(stat.rpartition(")")[2].split()[19])


def unpack_prefix() -> str:
    """The prefix of this process's unpack folders: ``wfbench-worker-PID-START-`` (START: the process's start time).

    The start time tells a folder whose process is gone from one whose pid was reused.
    """
    return f"{UNPACK_PREFIX}{os.getpid()}-{_start_time(os.getpid()) or 0}-"


def stale_unpack_dirs(root: str | Path) -> list[Path]:
    """The unpack folders under ``root`` (this user's) whose worker process is gone: what a killed worker left."""
    out = []
    try:
        entries = list(Path(root).iterdir())
    except OSError:
        return []
    for path in entries:
        m = _UNPACK_DIR.match(path.name)
        if m is None or path.is_symlink() or not path.is_dir():
            continue
        try:
            if path.stat().st_uid != os.getuid():
                continue
        except OSError:
            continue
        pid, start = int(m.group(1)), int(m.group(2))
        now = _start_time(pid)
        if now is None or (start and now and now != start):
            out.append(path)
    return sorted(out)


def failure_reason(exc: BaseException) -> str:
    """The one line a failed submission shows: the sandbox's ``reason``, a PolicyError's message, or the error."""
    reason = getattr(exc, "reason", None)
    if isinstance(reason, str) and reason:
        return reason
    if isinstance(exc, PolicyError):
        return exc.message.splitlines()[0] if exc.message else one_line(exc)
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def aggregate(frame: pd.DataFrame) -> dict[str, Any]:
    """A finished submission's result: the episode count and each KPI's mean, 25% and 75% quantile.

    Over every row, and per scenario where the rows name theirs (a track of several scenarios).
    """
    def kpis(df: pd.DataFrame) -> dict[str, dict[str, float]]:
        return {k: {"mean": m, "q25": lo, "q75": hi} for k, (m, lo, hi) in summarize(df, KPI_COLUMNS).items()}

    out: dict[str, Any] = {"episodes": len(frame), "kpis": kpis(frame)}
    scenarios = [s for s in frame["scenario"].unique() if s]
    if scenarios:
        out["scenarios"] = {s: {"episodes": int((frame["scenario"] == s).sum()),
                                "kpis": kpis(frame[frame["scenario"] == s])} for s in scenarios}
    return out


class OverBudget(Exception):
    """The submission used its whole time budget (:attr:`Worker.job_time_s`): the policy's failure, "timed out"."""


class _Heartbeat(threading.Thread):
    """Renews a claim's lease every ``every`` seconds until stopped; sets :attr:`lost` when it is refused.

    Each renewal stores the seconds ``spent()`` so far with the submission.
    """

    def __init__(self, c: Claim, every: float, spent: Callable[[], float] | None = None):
        super().__init__(name=f"heartbeat-{c.submission_id}", daemon=True)
        self.claim, self.every, self.spent = c, every, spent
        self.lost = threading.Event()
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.wait(self.every):
            try:
                ok = heartbeat(self.claim, self.spent() if self.spent else None)
            except sa.exc.SQLAlchemyError:  # the database did not answer this time: the lease covers a few misses
                continue
            if not ok:
                self.lost.set()
                return

    def stop(self) -> None:
        self.done.set()
        self.join(5)


@dataclass
class Progress:
    """Where a claimed job stands, for a runner's limits: units stored of all, and the worker seconds used so far.

    ``check()`` raises :class:`~wfbench.leaderboard.board.queue.LeaseLost` once the job's lease
    is gone: a runner calls it before each chunk it starts, the worker before each write.
    """

    done: int
    total: int
    spent: Callable[[], float]
    check: Callable[[], None] = lambda: None


Run = Callable[[str, ScenarioConfig, list[int]], Iterator[pd.DataFrame]]
"""``run(scenario, config, seeds)``: the rows of those seeds, one frame per finished chunk."""


class Runner(Protocol):
    """How a worker evaluates a claimed submission: the hosted board's :class:`SandboxRunner`, or the local one's.

    The local board's (:class:`wfbench.leaderboard.local.LocalRunner`) plays the chunks in a
    child process with today's evaluator and adds each row's provenance (:meth:`record`).
    """

    def units(self, board: Board, sub: Submission) -> list[tuple[str, int, int]]:
        """The (scenario, seed index, seed) the submission runs."""

    def open(self, board: Board, sub: Submission, progress: Progress) -> AbstractContextManager[Run]:
        """What runs the submission's chunks, ready (a package unpacked, a policy loaded) for as long as it is open."""

    def record(self, conn: sa.engine.Connection, rows: list[dict[str, Any]]) -> None:
        """Store what the board keeps beside the rows just inserted, in the same transaction (or nothing)."""


def unpack_root(work_dir: str | Path | None) -> Path:
    """The folder packages are unpacked under: ``work_dir``, or the temporary folder."""
    return Path(work_dir) if work_dir is not None else Path(tempfile.gettempdir())


class SandboxRunner:
    """The hosted board's runner: each chunk of the submission's package in the sandbox, within its time budget.

    Args:
        evaluator: what runs a chunk (default :func:`sandbox_evaluator`).
        unpack: what unpacks a package into a folder (default :func:`package_unpacker`).
        limits: the sandbox's limits (:class:`wfbench.harness.isolation.sandbox.Limits`; None: its defaults).
        chunk_size: seeds per evaluator call and per stored transaction.
        job_time_s: worker seconds one upload may use per scenario of its track, over
            every attempt (:data:`JOB_TIME_S`).
        work_dir: where packages are unpacked (default: the temporary folder).
    """

    def __init__(self, evaluator: Evaluator = sandbox_evaluator, unpack: Unpacker = package_unpacker,
                 limits: Any = None, chunk_size: int = DEFAULT_CHUNK, job_time_s: float = JOB_TIME_S,
                 work_dir: str | Path | None = None):
        if chunk_size < 1:
            raise ValueError(f"chunk size {chunk_size} is not allowed; allowed: 1 or more")
        if not (isinstance(job_time_s, int | float) and math.isfinite(job_time_s) and job_time_s > 0):
            raise ValueError(f"job time {job_time_s!r} s is not allowed; allowed: seconds > 0")
        self.evaluator, self.unpack, self.limits = evaluator, unpack, limits
        self.chunk_size, self.job_time_s = chunk_size, float(job_time_s)
        self.work_dir = unpack_root(work_dir)

    def units(self, board: Board, sub: Submission) -> list[tuple[str, int, int]]:
        return board.units(sub)

    def record(self, conn: sa.engine.Connection, rows: list[dict[str, Any]]) -> None:
        return None

    def budget(self, board: Board, sub: Submission) -> float:
        """The worker seconds ``sub`` may use over every attempt: :attr:`job_time_s` per scenario of its track."""
        return self.job_time_s * len(board.track(sub.track).configs())

    def _chunk_limits(self, board: Board, sub: Submission, progress: Progress) -> Any:
        """The sandbox's limits for the next chunk: its wall limit is what is left of the budget (OverBudget: none)."""
        budget = self.budget(board, sub)
        left = budget - progress.spent()
        if left <= 0:
            raise OverBudget(f"used its time budget of {budget:g} s of worker time per upload ({self.job_time_s:g} s "
                             f"per scenario of its track) with {progress.done} of {progress.total} episodes done")
        from wfbench.harness.isolation.sandbox import Limits

        limits = self.limits if self.limits is not None else Limits()
        return dataclasses.replace(limits, wall_time_s=min(limits.wall_time_s, left))

    @contextmanager
    def open(self, board: Board, sub: Submission, progress: Progress) -> Iterator[Run]:
        data = board.package(sub.package_sha)
        if data is None:
            raise BoardError(f"package {sub.package_sha} is missing from the board")
        secret, context = board.key_secret(), hidden.key_context(sub.track, sub.phase)
        self.work_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=unpack_prefix(), dir=self.work_dir) as tmp:
            package_dir = Path(tmp) / "policy"
            package_dir.mkdir()
            self.unpack(data, package_dir)

            def run(scenario: str, config: ScenarioConfig, seeds: list[int]) -> Iterator[pd.DataFrame]:
                for i in range(0, len(seeds), self.chunk_size):
                    progress.check()  # a lost lease costs no further chunk
                    limits = self._chunk_limits(board, sub, progress)
                    yield self.evaluator(package_dir, sub.entry, config, seeds[i:i + self.chunk_size], limits,
                                         secret, context)

            yield run


class Worker:
    """Claims and evaluates jobs of one board.

    Args:
        board: the board (its database).
        worker_id: the name stored as the lease's owner (default ``host:pid``).
        lease_s: the lease in seconds; renewed every third of it.
        chunk_size: the :class:`SandboxRunner`'s seeds per evaluator call and stored transaction.
        limits: the :class:`SandboxRunner`'s sandbox limits.
        evaluator: the :class:`SandboxRunner`'s evaluator of a chunk.
        unpack: the :class:`SandboxRunner`'s unpacker of a package.
        say: where progress lines go (default: stderr).
        job_time_s: the :class:`SandboxRunner`'s time budget per upload, per scenario of its track.
        work_dir: where the :class:`SandboxRunner` unpacks packages.
        runner: how a claimed submission runs (default: the :class:`SandboxRunner` of the above,
            which is not built when a runner is given).
    """

    def __init__(self, board: Board, worker_id: str | None = None, lease_s: float = DEFAULT_LEASE_S,
                 chunk_size: int = DEFAULT_CHUNK, limits: Any = None, evaluator: Evaluator = sandbox_evaluator,
                 unpack: Unpacker = package_unpacker, say: Callable[[str], None] | None = None,
                 job_time_s: float = JOB_TIME_S, work_dir: str | Path | None = None, runner: Runner | None = None):
        if not lease_s > 0:
            raise ValueError(f"lease {lease_s:g} s is not allowed; allowed: seconds > 0")
        if runner is None:
            runner = SandboxRunner(evaluator, unpack, limits, chunk_size, job_time_s, work_dir)
        self.runner: Runner = runner
        # where killed workers' unpack folders are looked for: the sandbox's, or the folder it would use
        self.work_dir = getattr(runner, "work_dir", None) or unpack_root(work_dir)
        self.board = board
        self.worker_id = worker_id or f"{socket.gethostname()}:{os.getpid()}"
        self.lease_s = float(lease_s)
        self.say = say or (lambda line: print(f"wfbench worker {self.worker_id}: {line}", file=sys.stderr,
                                              flush=True))

    def run(self, once: bool = False, poll_s: float = 2.0, stop: threading.Event | None = None) -> int:
        """Claim and evaluate jobs until ``stop`` is set (``once``: until the queue is empty); returns jobs handled.

        It first removes the unpack folders killed workers left (:meth:`clean_stale`).
        """
        self.clean_stale()
        handled = 0
        while stop is None or not stop.is_set():
            try:
                state = self.run_one()
            except sa.exc.OperationalError as exc:  # the database went away for a while: its job's lease expires
                self.say(f"database error: {one_line(exc.orig or exc)}; trying again in {poll_s:g} s")
                state = None
            if state == "requeued":  # a fault of this machine's: give it a moment before the next claim
                handled += 1
                if stop is not None:
                    stop.wait(poll_s)
                else:
                    time.sleep(poll_s)
                continue
            if state is None:
                if once:
                    break
                if stop is not None:
                    stop.wait(poll_s)
                else:
                    time.sleep(poll_s)
            else:
                handled += 1
        return handled

    def clean_stale(self) -> list[Path]:
        """Remove the unpack folders under :attr:`work_dir` whose worker process is gone; the folders removed."""
        gone = stale_unpack_dirs(self.work_dir)
        for path in gone:
            shutil.rmtree(path, ignore_errors=True)
        if gone:
            self.say(f"removed {len(gone)} unpack folder{'s' if len(gone) != 1 else ''} left by workers that are "
                     f"gone: {', '.join(p.name for p in gone)}")
        return gone

    def run_one(self, submission_id: int | None = None) -> str | None:
        """Claim one job and evaluate it: ``done``, ``failed``, ``requeued`` (a board fault) or ``lost``; None if none.

        ``submission_id``: claim that submission's job only (the local board's worker).

        After a :class:`~wfbench.harness.isolation.sandbox.SandboxUnavailable` the job is handed back
        and the error raised: this worker cannot run any job.
        """
        c = claim(self.board.engine, self.worker_id, self.lease_s, submission_id=submission_id)
        if c is None:
            return None
        self.say(f"claimed submission {c.submission_id} (attempt {c.attempt}, fence {c.fence})")
        started = time.monotonic()

        def spent() -> float:
            return c.spent_s + (time.monotonic() - started)

        beat = _Heartbeat(c, self.lease_s / 3, spent)
        beat.start()
        try:
            state = self.process(c, beat.lost, spent)
        finally:
            beat.stop()
        self.say(f"submission {c.submission_id}: {state}")
        return state

    def process(self, c: Claim, lost: threading.Event | None = None,
                spent: Callable[[], float] | None = None) -> str:
        """Evaluate a claimed job's missing units and finish it; ``lost`` (set by the heartbeat) stops it early.

        ``spent()``: the worker seconds the submission has used so far (default: as at the claim).
        """
        sub = self.board.submission(c.submission_id)
        assert sub is not None, f"claimed submission {c.submission_id} does not exist"
        spent = spent or (lambda: c.spent_s)
        log: list[str] = []
        try:
            try:
                self._evaluate(c, sub, lost, log, spent)
                frame = self.board.rows(sub.id)
                finish(c, "done", "", aggregate(frame), log="".join(log), spent_s=spent())
                return "done"
            except LeaseLost:
                raise
            except OverBudget as exc:
                return self._fail(c, str(exc), log, exc, "timed out", spent())
            except (PolicyError, ValueError) as exc:  # the policy's (or its package's) failure: final, with its reason
                return self._fail(c, failure_reason(exc), log, exc, failure_kind(exc), spent())
            except sa.exc.SQLAlchemyError:
                raise  # the database: the lease expires and another worker (or a retry) takes it
            except Exception as exc:  # noqa: BLE001 - the board's: no sandbox, a full disk, this worker's own error
                state = self._release(c, exc, spent())
                if _is_unavailable(exc):
                    raise
                return state
        except LeaseLost as exc:
            self.say(str(exc))
            return "lost"

    def _release(self, c: Claim, exc: BaseException, spent_s: float) -> str:
        what = "disk full" if isinstance(exc, OSError) and exc.errno in DISK_FULL else \
            "the sandbox did not start" if _is_unavailable(exc) else "the worker failed"
        reason = f"{what}: {failure_reason(exc)}"
        state = release(c, reason, spent_s)
        self.say(f"submission {c.submission_id}: a board fault, not the policy's ({reason}); "
                 + ("queued again" if state == "requeued" else f"failed after {c.attempt} attempts"))
        if not isinstance(exc, OSError | BoardError) and not _is_unavailable(exc):
            self.say("".join(traceback.format_exception(exc)).rstrip())
        return state

    def _fail(self, c: Claim, reason: str, log: list[str], exc: BaseException, kind: str, spent_s: float) -> str:
        extra = getattr(exc, "log", "")
        finish(c, "failed", reason, None, log="".join(log) + (extra if isinstance(extra, str) else ""), kind=kind,
               spent_s=spent_s)
        self.say(f"submission {c.submission_id} failed: {reason}")
        return "failed"

    def _evaluate(self, c: Claim, sub: Submission, lost: threading.Event | None, log: list[str],
                  spent: Callable[[], float]) -> None:
        configs = self.board.track(sub.track).configs()
        done = self.board.done_units(sub.id)
        missing = [u for u in self.runner.units(self.board, sub) if (u[0], u[1]) not in done]
        if not missing:
            return
        def check() -> None:
            if lost is not None and lost.is_set():
                raise LeaseLost(f"submission {c.submission_id}: worker {c.worker_id} lost its lease (a heartbeat "
                                "was refused: another worker claimed the job, or its owner withdrew it); nothing "
                                "more was written")

        progress = Progress(len(done), len(missing) + len(done), spent, check)
        with self.runner.open(self.board, sub, progress) as run:
            for scenario, units in _by_scenario(missing):
                index = {seed: i for _, i, seed in units}
                for frame in run(scenario, configs[scenario], list(index)):
                    check()
                    text = frame.attrs.get("log")
                    if isinstance(text, str) and text:
                        log.append(text)
                    progress.done += write_rows(c, _rows(frame, scenario, index), spent_s=spent(),
                                                then=self.runner.record)
        stored = len(self.board.done_units(sub.id))
        if stored < progress.total:
            raise ValueError(f"only {stored} of {progress.total} episodes were stored")


def _by_scenario(units: list[tuple[str, int, int]]) -> list[tuple[str, list[tuple[str, int, int]]]]:
    """The units grouped by scenario, in order."""
    out: list[tuple[str, list[tuple[str, int, int]]]] = []
    for u in units:
        if out and out[-1][0] == u[0]:
            out[-1][1].append(u)
        else:
            out.append((u[0], [u]))
    return out


def _rows(frame: pd.DataFrame, scenario: str, index: dict[int, int]) -> list[dict[str, Any]]:
    """The evaluator's rows as the queue stores them (seed index, scenario and, unless they name it, the machine).

    A frame without a ``machine`` column ran in the sandbox (one process).
    """
    seeds = frame["seed"].astype(int).tolist()
    if not set(seeds) <= set(index) or len(set(seeds)) != len(seeds):
        raise ValueError(f"the evaluation returned seeds other than those asked ({len(frame)} rows for "
                         f"{len(index)} seeds)")
    budget = frame.attrs.get("budget", {})
    where = machine_line({**(budget.get("machine") or machine()), "backend": "sandbox", "workers": 1})
    out = []
    for r in frame.to_dict("records"):
        row = {c: r[c] for c in ROW_COLUMNS}
        row.update({c: r.get(c, math.nan) for c in BUDGET_COLUMNS})
        row.update(scenario=scenario, seed=int(r["seed"]), seed_index=index[int(r["seed"])],
                   machine=r.get("machine") or where)
        out.append(row)
    return out


# -- the command ----------------------------------------------------------------------------------------------


def _is_unavailable(exc: BaseException) -> bool:
    return any(k.__name__ == "SandboxUnavailable" for k in type(exc).__mro__)


class _Stopped(BaseException):
    """SIGTERM: leave at once (the sandbox and the temporary folder are cleaned up on the way out)."""


def _on_term(signum: int, frame: Any) -> None:
    raise _Stopped()


def run_worker(server: str, worker_id: str | None = None, lease_s: float = DEFAULT_LEASE_S, once: bool = False,
               poll_s: float = 2.0, chunk_size: int = DEFAULT_CHUNK, tracks: Mapping[str, Any] | None = None,
               evaluator: Evaluator | None = None, unpack: Unpacker | None = None, limits: Any = None,
               job_time_s: float = JOB_TIME_S) -> int:
    """What ``wfbench worker`` runs; its exit status.

    Refuses to start (status 2, one line) without the sandbox, a bad database URL or
    lease; stops on SIGTERM (status 143) leaving the job to the lease's expiry.
    ``tracks``: the board's tracks (default: every track, as ``wfbench serve``'s).
    ``limits``: the sandbox's :class:`~wfbench.harness.isolation.sandbox.Limits` (None: its defaults).
    ``job_time_s``: the time budget per upload, per scenario of its track (:class:`Worker`).
    ``evaluator`` and ``unpack``: for the tests only (the sandbox is checked only when
    the evaluator is the sandbox's).
    """
    try:
        if evaluator is None:
            check_sandbox()
        board = Board(server, tracks=tracks)
        board.create()
        worker = Worker(board, worker_id, lease_s, chunk_size, limits=limits, evaluator=evaluator or sandbox_evaluator,
                        unpack=unpack or package_unpacker, job_time_s=job_time_s)
    except (BoardError, ValueError) as exc:
        print(f"wfbench worker: error: {failure_reason(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:
        if _is_unavailable(exc):
            print(f"wfbench worker: error: {exc}; the worker never runs a submission outside the sandbox",
                  file=sys.stderr)
            return 2
        raise
    previous = signal.signal(signal.SIGTERM, _on_term)
    try:
        worker.say(f"serving {board.engine.url.render_as_string(hide_password=True)} (lease {lease_s:g} s)")
        worker.run(once=once, poll_s=poll_s)
        return 0
    except Exception as exc:
        if not _is_unavailable(exc):
            raise
        print(f"wfbench worker: error: {exc}; the job is back in the queue for another worker (a board fault, not "
              "the policy's)", file=sys.stderr)
        return 2
    except _Stopped:
        worker.say("stopped by SIGTERM; the job's lease will expire and another worker resumes it")
        return 143
    finally:
        signal.signal(signal.SIGTERM, previous)
        board.close()
