"""Evaluate a policy on a track's test seeds in a child process and store one row per seed.

The policy runs in a child process (spawned: nothing of the parent leaks in) with an
address-space limit (``memory_mb``, ``RLIMIT_AS``, inherited by its workers); the parent
enforces the wall-time limit and is the only writer of the store. The child sends each
finished chunk of seeds as soon as it is done and the parent commits it in one
transaction, so an interruption loses at most the chunks in flight. A policy that
cannot be loaded is a user error (nothing is stored); one that raises, returns
malformed actions, hangs past the limit, exhausts its memory or kills its process
marks the submission ``failed`` with the reason, and every stored row and every other
submission stay as they were. Submitting the same name and policy again resumes with
the seeds still missing.
"""

from __future__ import annotations

import getpass
import multiprocessing as mp
import os
import signal
import time
import traceback
from dataclasses import dataclass
from typing import Any

from leaderboard.store import ROW_COLUMNS, Store, Submission
from leaderboard.tracks import Track, get_track
from wfbench import __version__

DEFAULT_WALL_TIME_S = 3600.0
DEFAULT_MEMORY_MB = 8192
BUILTIN_ENTRIES = ("random", "heuristic", "heuristic-stochastic", "solver", "solver-dispatch", "solver-workforce",
                   "solver-positioning")


class SubmitError(Exception):
    """The submission cannot start (unknown track or policy, name taken, bad limits): one line, exit 2."""


@dataclass(frozen=True)
class Outcome:
    submission: Submission
    status: str  # complete | failed
    reason: str
    new_rows: int
    stored_rows: int
    seconds: float


def _child(conn, policy_spec: str, config, seeds, backend, workers, address, chunk_size, memory_mb) -> None:
    """Runs in the child process: load the policy, then stream finished rows to the parent.

    The child leads its own process group, so the parent can stop it together with any
    worker processes it started.
    """
    try:
        os.setsid()
    except OSError:  # already a group leader
        pass
    if memory_mb:
        try:
            import resource

            limit = int(memory_mb) * 1024 * 1024
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        except (ImportError, ValueError, OSError) as exc:  # not on this platform: say so, run unlimited
            conn.send(("note", f"memory limit not applied: {exc}"))
    try:
        from policies import get

        policy = get(policy_spec)
    except BaseException as exc:  # noqa: BLE001 - anything the user's import raises is a load error
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {type(exc).__name__}: {exc}"))
        return
    conn.send(("ready",))
    try:
        from wfbench.backends import run_chunks, shutdown_pools
        from wfbench.evaluate import _frame

        target = policy if backend == "serial" else policy_spec
        for batch in run_chunks(target, config, seeds, backend=backend, workers=workers, address=address,
                                chunk_size=chunk_size, threads=1 if backend == "serial" else None):
            rows = _frame([batch], config, policy_spec)[["seed", *ROW_COLUMNS]].to_dict("records")
            conn.send(("rows", rows))
        shutdown_pools()  # before saying done: the parent may stop this process right after
        conn.send(("done",))
    except MemoryError:
        conn.send(("error", f"the policy ran out of memory (limit {memory_mb} MiB)"))
    except BaseException as exc:  # noqa: BLE001 - report any failure of the user's policy
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""
        text = str(exc).splitlines()[0] if str(exc) else ""
        conn.send(("error", f"{type(exc).__name__}: {text}{where}"))


def submit(track: str | Track, policy: str, name: str, submitter: str | None = None, db: Any = None,
           backend: str = "process", workers: int | None = None, address: str | None = None,
           wall_time_s: float = DEFAULT_WALL_TIME_S, memory_mb: int | None = DEFAULT_MEMORY_MB,
           chunk_size: int | None = None, progress: bool = False, builtin: bool = False) -> Outcome:
    """Evaluate ``policy`` (a registry name or ``module:attr``) on the track's test seeds and store the rows."""
    from wfbench.backends import check_backend

    try:
        tr = track if isinstance(track, Track) else get_track(track)
        check_backend(backend, address)
    except ValueError as exc:
        raise SubmitError(str(exc)) from None
    if not isinstance(policy, str) or not policy:
        raise SubmitError("--policy must be a registry name or a module:attr entry point")
    if not (wall_time_s > 0):
        raise SubmitError(f"wall time {wall_time_s!r} is not allowed; allowed: seconds > 0")
    if memory_mb is not None and memory_mb < 256:
        raise SubmitError(f"memory limit {memory_mb} MiB is not allowed; allowed: >= 256 MiB")
    if ":" not in policy:  # a registry name or composite: check it here, no user code runs
        from policies import get

        try:
            get(policy)
        except ValueError as exc:
            raise SubmitError(str(exc)) from None
    submitter = submitter or getpass.getuser()
    store = db if isinstance(db, Store) else Store(db)
    t0 = time.perf_counter()
    existing = store.find(tr.name, name)
    if existing is not None and existing.policy != policy:
        raise SubmitError(f"the name {name!r} is already taken on track {tr.name} by policy {existing.policy!r}; "
                          "choose another --name")
    done = store.done_seeds(existing.id) if existing else set()
    missing = [s for s in tr.test_seeds if s not in done]
    if existing is not None and not missing:
        if existing.status != "complete":
            store.set_status(existing.id, "complete", "")
        sub = store.find(tr.name, name)
        return Outcome(sub, "complete", "", 0, len(done), time.perf_counter() - t0)  # type: ignore[arg-type]
    chunk = chunk_size or 5
    ctx = mp.get_context("spawn")
    parent_conn, child_conn = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child_conn, policy, tr.config, missing, backend, workers, address,
                                            chunk, memory_mb), daemon=False)
    proc.start()
    child_conn.close()
    bar = None
    sub: Submission | None = existing
    new_rows = 0
    status, reason = "failed", ""
    deadline = time.monotonic() + wall_time_s
    try:
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                reason = (f"exceeded the wall-time limit of {wall_time_s:g} s after "
                          f"{len(done) + new_rows} of {len(tr.test_seeds)} seeds")
                break
            if parent_conn.poll(min(remaining, 0.25)):
                try:
                    msg = parent_conn.recv()
                except EOFError:
                    msg = None
                if msg is None:
                    proc.join(5)
                    reason = _death_reason(proc.exitcode, memory_mb)
                    break
                kind = msg[0]
                if kind == "load_error":
                    raise SubmitError(msg[1])
                if kind == "ready":
                    sub = store.open_submission(tr, name, policy, submitter, __version__, builtin=builtin)
                    if progress:
                        from tqdm.auto import tqdm

                        bar = tqdm(total=len(tr.test_seeds), initial=len(done), desc=f"{name} on {tr.name}",
                                   unit="episode", leave=False)
                elif kind == "rows":
                    assert sub is not None
                    new_rows += store.add_results(sub, __version__, msg[1])
                    if bar:
                        bar.update(len(msg[1]))
                elif kind == "done":
                    status = "complete"
                    break
                elif kind == "error":
                    reason = msg[1]
                    break
            elif not proc.is_alive():
                if parent_conn.poll():
                    continue  # drain what it sent before dying
                reason = _death_reason(proc.exitcode, memory_mb)
                break
    finally:
        if bar:
            bar.close()
        if status == "complete":
            proc.join(30)  # it says done after shutting its workers down; let it exit cleanly
        _stop(proc)
        parent_conn.close()
    if sub is None:  # the child died before loading the policy
        raise SubmitError(f"the evaluation of {policy!r} could not start: {reason}")
    stored = len(store.done_seeds(sub.id))
    if status == "complete" and stored < len(tr.test_seeds):
        status, reason = "failed", f"only {stored} of {len(tr.test_seeds)} seeds were stored"
    store.set_status(sub.id, status, reason)
    return Outcome(store.find(tr.name, name), status, reason, new_rows, stored,  # type: ignore[arg-type]
                   time.perf_counter() - t0)


def _stop(proc) -> None:
    """Kill the child's whole process group (it and any workers it started), then reap it."""
    if proc.pid is not None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    proc.join(10)


def _death_reason(exitcode: int | None, memory_mb: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            sig = signal.Signals(-exitcode).name
        except ValueError:
            sig = str(-exitcode)
        hint = f"; out of memory? (limit {memory_mb} MiB)" if sig == "SIGKILL" else ""
        return f"the evaluation process was killed by {sig}{hint}"
    return f"the evaluation process exited unexpectedly (exit code {exitcode})"


def seed_builtins(track: str | Track, db: Any = None, names: tuple[str, ...] = BUILTIN_ENTRIES,
                  progress: bool = False, **kwargs: Any) -> list[Outcome]:
    """Submit (or resume) the built-in policies under their registry names."""
    return [submit(track, n, n, submitter="wfbench", db=db, builtin=True, progress=progress, **kwargs)
            for n in names]
