"""The local board's runner: the worker's chunks played by today's evaluator in a child process, no sandbox.

:class:`LocalRunner` starts a loky child (no ``__main__`` guard needed) with an address-space
limit, which loads the policy once and says its fingerprint and budget; the in-process
:class:`~wfbench.leaderboard.board.worker.Worker` then asks it for each scenario's missing
seeds, stores the rows it streams back with their provenance, and the runner enforces the
wall time. Every failure of the policy or its process is a :class:`LocalFailure`.
``docs/leaderboard.md``, "One board".
"""

from __future__ import annotations

import math
import os
import signal
import time
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pandas as pd
from joblib.externals.loky.backend.context import get_context
from wfbench.leaderboard.board.db import Board, Submission
from wfbench.leaderboard.board.worker import Progress, Run
from wfbench.leaderboard.fingerprint import is_entry_point, policy_fingerprint
from wfbench.leaderboard.rows import ROW_COLUMNS, SubmitError, scrub_paths
from wfbench.leaderboard.store import add_provenance
from wfbench.leaderboard.tracks import Track

from wfbench import __version__
from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution, run_chunks, shutdown_pools
from wfbench.harness.budget import BUDGET_COLUMNS, machine_line, policy_budget
from wfbench.harness.guard import PolicyError, PolicyLoadError, load_policy, one_line
from wfbench.harness.runner import results_frame


class LocalFailure(PolicyError):
    """The policy (or its process) failed: ``message`` whole for the user, ``reason`` as the board stores it."""

    def __init__(self, message: str, trace: str = ""):
        super().__init__(message, trace)
        self.reason = scrub_paths(message, os.getcwd())  # no absolute path of the submitter's machine on the board


def _where(exc: BaseException) -> str:
    tb = traceback.extract_tb(exc.__traceback__)
    return f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""


def _child(conn, policy_spec: str, configs, execution: Execution, memory_mb, act_timeout_s) -> None:
    """Runs in the child process: load the policy, then evaluate what the parent asks for.

    Messages to the parent: ``("note", text)``, ``("load_error", line, trace)``,
    ``("ready", fingerprint, detail, budget)`` (the first two ``None`` unless the policy is an
    entry point), then per request ``("rows", rows)`` for each finished chunk and ``("done",)``,
    or ``("error", line, trace)``. From the parent: ``("run", scenario, seeds)`` (scenario a
    key of ``configs``: ``""`` on a one-scenario track) or ``("stop",)``. The child leads its
    own process group, so the parent can stop it together with any worker processes it started.
    """
    try:
        os.setsid()
    except OSError:  # already a group leader
        pass
    if memory_mb:
        try:
            import resource  # POSIX only: on other platforms the limit is reported as not applied

            limit = int(memory_mb) * 1024 * 1024
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        except (ImportError, ValueError, OSError) as exc:  # not on this platform: say so, run unlimited
            conn.send(("note", f"memory limit not applied: {exc}"))
    try:
        loaded = load_policy(policy_spec, act_timeout_s)
    except PolicyLoadError as exc:
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {exc}", ""))
        return
    except PolicyError as exc:
        conn.send(("load_error", exc.message, exc.trace))
        return
    except BaseException as exc:  # noqa: BLE001 - anything the user's import raises is a load error
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {one_line(exc)}{_where(exc)}",
                   traceback.format_exc()))
        return
    if loaded.guard is not None and getattr(loaded.policy, "reads_trace", False):
        conn.send(("load_error", f"policy {policy_spec!r} declares reads_trace = True: it reads the episode's "
                   "future, and the leaderboard ranks deployable policies only (its 'not deployable' section "
                   "holds wfbench's own oracles); compare it with 'wfbench compare' instead", ""))
        return
    fingerprint = detail = None
    if is_entry_point(policy_spec):
        try:
            fingerprint, detail = policy_fingerprint(policy_spec, loaded.policy)
        except SubmitError as exc:
            conn.send(("load_error", str(exc), ""))
            return
        except Exception as exc:  # noqa: BLE001 - the policy's params() raised
            conn.send(("load_error", f"policy {policy_spec!r}: its params() raised {one_line(exc)}{_where(exc)}",
                       traceback.format_exc()))
            return
    try:
        budget = policy_budget(policy_spec, loaded.policy)
    except (OSError, ValueError) as exc:  # a checkpoint or tuned file that went away since it loaded
        budget = {"kind": "other", "error": one_line(exc)}
    conn.send(("ready", fingerprint, detail, budget))
    serial = execution.backend == "serial"
    where = {"backend": execution.backend, "workers": 1 if serial else execution.workers or os.cpu_count() or 1}
    run = execution.replace(threads=1 if serial else None)  # serial: one numba thread, as each parallel worker
    while (msg := conn.recv())[0] == "run":
        scenario, seeds = msg[1], msg[2]
        try:
            for batch in run_chunks(loaded, configs[scenario], seeds, run):
                frame = results_frame([batch], configs[scenario], policy_spec)[["seed", *ROW_COLUMNS,
                                                                               *BUDGET_COLUMNS]]
                conn.send(("rows", [{**row, "machine": machine_line({**batch.machine, **where}), "scenario": scenario}
                                    for row in frame.to_dict("records")]))
            shutdown_pools()  # before saying done: the parent may stop this process right after
            conn.send(("done",))
        except PolicyError as exc:
            shutdown_pools(kill_workers=True)  # the other chunks' results would not be stored
            conn.send(("error", exc.message, exc.trace))
            return
        except MemoryError:
            conn.send(("error", f"the policy ran out of memory (limit {memory_mb} MiB)", traceback.format_exc()))
            return
        except BaseException as exc:  # noqa: BLE001 - report any failure of the evaluation
            shutdown_pools(kill_workers=True)
            conn.send(("error", f"{one_line(exc)}{_where(exc)}", traceback.format_exc()))
            return


def _death_reason(exitcode: int | None, memory_mb: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            sig = signal.Signals(-exitcode).name
        except ValueError:
            sig = str(-exitcode)
        hint = f"; out of memory? (limit {memory_mb} MiB)" if sig == "SIGKILL" else ""
        return f"the evaluation process was killed by {sig}{hint}"
    return f"the evaluation process exited unexpectedly (exit code {exitcode})"


class RemainingTime:
    """An honest estimate of the time left over episodes of unequal cost (a suite track's scenarios).

    An episode of ``city`` costs a hundred of ``small``, so a count of episodes done says little
    about the time left. The cost of a scenario's episode is measured (the mean CPU seconds its
    finished rows report); a scenario not started yet is estimated from its size (slots times
    horizon) at the cost per unit of size measured on the scenarios that have finished
    episodes. The wall seconds per unit of cost (which folds in the workers running side by
    side) come from what finished since it was made. Before the first rows there is no
    estimate (``None``), never a guess.

    Args:
        units: every (scenario, seed) the entry needs.
        configs: each scenario's config (``Track.configs()``).
        done: the units already stored (a resumed entry).
    """

    def __init__(self, units: list[tuple[str, int]], configs: dict[str, Any], done: set[tuple[str, int]]):
        self.size = {sc: float((c.max_facilities + c.max_personnel) * c.horizon) for sc, c in configs.items()}
        self.left: dict[str, int] = {}
        for sc, seed in units:
            if (sc, seed) not in done:
                self.left[sc] = self.left.get(sc, 0) + 1
        self.finished: dict[str, int] = {}
        self.cpu: dict[str, list[float]] = {}
        self.t0 = time.monotonic()

    def add(self, rows: list[dict[str, Any]]) -> None:
        """Count finished rows and their measured CPU seconds."""
        for row in rows:
            sc = row.get("scenario", "")
            self.left[sc] = max(0, self.left.get(sc, 0) - 1)
            self.finished[sc] = self.finished.get(sc, 0) + 1
            cpu = row.get("cpu_s")
            if cpu is not None and math.isfinite(cpu):
                self.cpu.setdefault(sc, []).append(float(cpu))

    def cost(self, scenario: str) -> float | None:
        """The estimated CPU seconds of one episode of ``scenario`` (None before any measurement)."""
        if self.cpu.get(scenario):
            return sum(self.cpu[scenario]) / len(self.cpu[scenario])
        measured = [sc for sc in self.cpu if self.cpu[sc]]
        if not measured:
            return None
        per_size = sum(self.cost(sc) for sc in measured) / sum(self.size[sc] for sc in measured)
        return per_size * self.size[scenario]

    def seconds_left(self) -> float | None:
        """Wall seconds until every unit is done, at the pace since the episodes started."""
        costs = {sc: self.cost(sc) for sc in self.size}
        if any(c is None for c in costs.values()):
            return None
        done_work = sum(n * costs[sc] for sc, n in self.finished.items())
        if done_work <= 0:
            return None
        left_work = sum(n * costs[sc] for sc, n in self.left.items())
        return (time.monotonic() - self.t0) * left_work / done_work

    def per_scenario(self) -> dict[str, float]:
        """CPU seconds of the finished episodes, per scenario."""
        return {sc: float(sum(v)) for sc, v in self.cpu.items()}


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.0f} min" if seconds < 5400 \
        else f"{seconds / 3600:.1f} h"


class LocalRunner:
    """A policy loaded in its child process, run for the local board's worker (a context manager: stops the child).

    Args:
        track: the track (its configs; its test seeds are the units, each its own index).
        policy: the registry name or ``module:attr`` entry point.
        execution: where the child plays the episodes; its ``chunk_size`` is the seeds per stored chunk.
        wall_time_s: the limit of the whole run, from the child's start.
        memory_mb: the child's address-space limit in MiB (``None``: none).
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy.

    Raises:
        SubmitError: the policy cannot be loaded, or its process did not start.
    """

    def __init__(self, track: Track, policy: str, execution: Execution, wall_time_s: float,
                 memory_mb: int | None, act_timeout_s: float | None):
        self.track, self.policy, self.execution = track, policy, execution
        self.wall_time_s, self.memory_mb = wall_time_s, memory_mb
        self.entry: Submission | None = None  # set by the caller once the entry is open: the rows' provenance
        self.clock: Any = None  # the progress bar's RemainingTime, once running
        self.failure: LocalFailure | None = None
        self._deadline = time.monotonic() + wall_time_s
        # loky's process: a fresh interpreter that does not re-import __main__ (multiprocessing's
        # spawn would run a guard-less calling script again in the child)
        ctx = get_context("loky")
        self._conn, child_conn = ctx.Pipe(duplex=True)
        self._proc = ctx.Process(target=_child, args=(child_conn, policy, track.configs(), execution, memory_mb,
                                                      act_timeout_s), daemon=False)
        self._proc.start()
        child_conn.close()
        self._ends = False  # the child said done or error: it stops by itself
        try:
            msg = self._next()
            while msg[0] == "note":
                msg = self._next()
            if msg[0] == "load_error":
                raise SubmitError(msg[1])
            if msg[0] != "ready":
                raise SubmitError(f"the evaluation of {policy!r} could not start: {msg[1]}")
        except LocalFailure as exc:
            self.close()
            raise SubmitError(f"the evaluation of {policy!r} could not start: {exc.message}") from None
        except BaseException:
            self.close()
            raise
        self.fingerprint, self.detail, self.budget = msg[1], msg[2], msg[3]

    def __enter__(self) -> LocalRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _next(self, done: int = 0, total: int = 0) -> tuple:
        """The child's next message; LocalFailure when the wall time runs out or the child dies."""
        while True:
            remaining = self._deadline - time.monotonic()
            if remaining <= 0:
                raise self._fail(f"exceeded the wall-time limit of {self.wall_time_s:g} s after {done} of {total} "
                                 f"{self.track.unit_word}")
            if self._conn.poll(min(remaining, 0.25)):
                try:
                    return self._conn.recv()
                except EOFError:
                    self._proc.join(5)
                    raise self._fail(_death_reason(self._proc.exitcode, self.memory_mb)) from None
            if not self._proc.is_alive() and not self._conn.poll():
                raise self._fail(_death_reason(self._proc.exitcode, self.memory_mb))

    def _fail(self, message: str, trace: str = "") -> LocalFailure:
        self.failure = LocalFailure(message, trace)
        return self.failure

    # -- the worker's runner --------------------------------------------------------------------------------
    def units(self, board: Board, sub: Submission) -> list[tuple[str, int, int]]:
        return [(sc, seed, seed) for sc, seed in self.track.units()]

    def record(self, conn: Any, rows: list[dict[str, Any]]) -> None:
        assert self.entry is not None, "the entry is opened before its job runs"
        add_provenance(conn, self.entry, __version__, rows)

    @contextmanager
    def open(self, board: Board, sub: Submission, progress: Progress) -> Iterator[Run]:
        self.clock = RemainingTime(self.track.units(), self.track.configs(), board.done_units(sub.id))
        bar = None
        if self.execution.progress:
            from tqdm.auto import tqdm

            # tqdm's own rate assumes episodes of equal cost: the estimate is RemainingTime's
            bar = tqdm(total=progress.total, initial=progress.done, desc=f"{sub.name} on {self.track.name}",
                       unit="episode", leave=False,
                       bar_format="{desc}: {percentage:3.0f}%|{bar}| {n}/{total} episodes [{elapsed}{postfix}]")
            bar.set_postfix_str("time left: after the first episodes", refresh=True)

        def run(scenario: str, config: ScenarioConfig, seeds: list[int]) -> Iterator[pd.DataFrame]:
            self._conn.send(("run", scenario, seeds))
            while True:
                msg = self._next(progress.done, progress.total)
                if msg[0] == "rows":
                    self.clock.add(msg[1])
                    if bar is not None:
                        left = self.clock.seconds_left()
                        bar.set_postfix_str("time left: " + ("after the first episodes of each size" if left is None
                                                             else f"about {_duration(left)}"), refresh=False)
                        bar.update(len(msg[1]))
                    yield pd.DataFrame(msg[1])
                elif msg[0] == "done":
                    return
                elif msg[0] == "error":
                    self._ends = True
                    raise self._fail(msg[1], msg[2])

        try:
            yield run
        finally:
            if bar is not None:
                bar.close()

    def close(self) -> None:
        """Stop the child: let it end by itself where it can, then kill its whole process group and reap it."""
        if self._proc.is_alive() and not self._ends and self.failure is None:
            try:
                self._conn.send(("stop",))
                self._ends = True
            except OSError:
                pass
        if self._ends:
            self._proc.join(30)  # it has shut its workers down; let it exit cleanly
        if self._proc.pid is not None:
            try:
                os.killpg(self._proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        self._proc.join(10)
        self._conn.close()
