"""Evaluate a policy on a track's test seeds in a child process and store one row per seed.

The policy runs in a child process (a fresh interpreter started by loky: nothing of the
parent leaks in, and ``__main__`` is not re-imported, so this works from a script
without a ``__main__`` guard) with an address-space limit (``memory_mb``,
``RLIMIT_AS``, inherited by its workers); the parent enforces the wall-time limit and
is the only writer of the store. The child sends each finished chunk of seeds as soon
as it is done and the parent commits it in one transaction, so an interruption loses
at most the chunks in flight. A policy that cannot be loaded is a user error (nothing
is stored); one that raises, returns malformed actions, overruns its act timeout
(``act_timeout_s`` per ``reset``/``act`` call, :mod:`wfbench.guard`), hangs past the
wall-time limit, exhausts its memory or kills its process marks the submission
``failed`` with a one-line reason naming its file and line, and every stored row and
every other submission stay as they were. Submitting the same name and policy again
resumes with the seeds still missing.
"""

from __future__ import annotations

import getpass
import os
import signal
import time
import traceback
from dataclasses import dataclass
from typing import Any

from joblib.externals.loky.backend.context import get_context

from leaderboard.store import ROW_COLUMNS, Store, Submission
from leaderboard.tracks import Track, get_track
from wfbench import __version__
from wfbench.backends import check_backend, run_chunks, shutdown_pools
from wfbench.guard import DEFAULT_ACT_TIMEOUT_S, PolicyError, PolicyLoadError, check_act_timeout, load_policy
from wfbench.runner import results_frame

DEFAULT_WALL_TIME_S = 3600.0
DEFAULT_MEMORY_MB = 8192
# heuristic-tuned, solver-tuned: tuned on paper-64's public seeds (policies/tuned/), entered as they are on every track
BUILTIN_ENTRIES = ("random", "heuristic", "heuristic-stochastic", "solver", "solver-dispatch", "solver-workforce",
                   "solver-positioning", "heuristic-tuned", "solver-tuned",
                   "oracle")  # oracle: shown apart, as not deployable


class SubmitError(Exception):
    """The submission cannot start (unknown track or policy, name taken, bad limits): one line, exit 2."""


@dataclass(frozen=True)
class Outcome:
    submission: Submission
    status: str  # complete | failed
    reason: str  # one line; empty when complete
    new_rows: int
    stored_rows: int
    seconds: float
    trace: str = ""  # the failure's whole traceback, formatted in the child (for --traceback)


def _where(exc: BaseException) -> str:
    tb = traceback.extract_tb(exc.__traceback__)
    return f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _child(conn, policy_spec: str, config, seeds, backend, workers, address, chunk_size, memory_mb,
           act_timeout_s) -> None:
    """Runs in the child process: load the policy, then stream finished rows to the parent.

    Messages: ``("note", text)``, ``("load_error", line, trace)``, ``("ready",)``,
    ``("rows", rows)``, ``("done",)``, ``("error", line, trace)``. The child leads its own
    process group, so the parent can stop it together with any worker processes it started.
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
        conn.send(("load_error", f"cannot load policy {policy_spec!r}: {_one_line(exc)}{_where(exc)}",
                   traceback.format_exc()))
        return
    if loaded.guard is not None and getattr(loaded.policy, "reads_trace", False):
        conn.send(("load_error", f"policy {policy_spec!r} declares reads_trace = True: it reads the episode's "
                   "future, and the leaderboard ranks deployable policies only (its 'not deployable' section "
                   "holds wfbench's own oracles); compare it with 'wfbench compare' instead", ""))
        return
    conn.send(("ready",))
    try:
        for batch in run_chunks(loaded, config, seeds, backend=backend, workers=workers, address=address,
                                chunk_size=chunk_size, threads=1 if backend == "serial" else None):
            rows = results_frame([batch], config, policy_spec)[["seed", *ROW_COLUMNS]].to_dict("records")
            conn.send(("rows", rows))
        shutdown_pools()  # before saying done: the parent may stop this process right after
        conn.send(("done",))
    except PolicyError as exc:
        shutdown_pools(kill_workers=True)  # the other chunks' results would not be stored
        conn.send(("error", exc.message, exc.trace))
    except MemoryError:
        conn.send(("error", f"the policy ran out of memory (limit {memory_mb} MiB)", traceback.format_exc()))
    except BaseException as exc:  # noqa: BLE001 - report any failure of the evaluation
        shutdown_pools(kill_workers=True)
        conn.send(("error", f"{_one_line(exc)}{_where(exc)}", traceback.format_exc()))


def submit(track: str | Track, policy: str, name: str, submitter: str | None = None, db: Any = None,
           backend: str = "process", workers: int | None = None, address: str | None = None,
           wall_time_s: float = DEFAULT_WALL_TIME_S, memory_mb: int | None = DEFAULT_MEMORY_MB,
           chunk_size: int | None = None, progress: bool = False, builtin: bool = False,
           act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S) -> Outcome:
    """Evaluate ``policy`` (a registry name or ``module:attr``) on the track's test seeds and store the rows.

    Args:
        track: a track name or :class:`~leaderboard.tracks.Track`.
        policy: a registry name or a ``module:attr`` entry point.
        name: the entry's name on the track; submitting it again resumes.
        submitter: who submits (default: the user name).
        db: a store path or :class:`~leaderboard.store.Store` (default: the user's store).
        backend: where the child runs the episodes (:mod:`wfbench.backends`).
        workers: processes or Ray tasks of the child.
        address: Ray cluster address.
        wall_time_s: the whole evaluation's limit in seconds.
        memory_mb: the child's address-space limit in MiB (``None``: none).
        chunk_size: seeds per stored chunk (default 5).
        progress: show a progress bar.
        builtin: mark the entry as one of wfbench's own.
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy in
            seconds; ``None`` or 0 for none.

    Returns:
        The outcome: ``complete``, or ``failed`` with a one-line reason and its trace.

    Raises:
        SubmitError: the submission cannot start (unknown track or policy, a policy that
            cannot be loaded, a name taken, bad limits); nothing is stored.
    """
    try:
        tr = track if isinstance(track, Track) else get_track(track)
        check_backend(backend, address)
        act_timeout_s = check_act_timeout(act_timeout_s)
    except ValueError as exc:
        raise SubmitError(str(exc)) from None
    if not isinstance(policy, str) or not policy:
        raise SubmitError("--policy must be a registry name or a module:attr entry point")
    if not (wall_time_s > 0):
        raise SubmitError(f"wall time {wall_time_s!r} is not allowed; allowed: seconds > 0")
    if memory_mb is not None and memory_mb < 256:
        raise SubmitError(f"memory limit {memory_mb} MiB is not allowed; allowed: >= 256 MiB")
    if ":" not in policy:  # a registry name or composite: check it here, no user code runs
        try:
            load_policy(policy)
        except PolicyLoadError as exc:
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
    # loky's process: a fresh interpreter that does not re-import __main__ (multiprocessing's
    # spawn would run a guard-less calling script again in the child)
    ctx = get_context("loky")
    parent_conn, child_conn = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child_conn, policy, tr.config, missing, backend, workers, address,
                                            chunk, memory_mb, act_timeout_s), daemon=False)
    proc.start()
    child_conn.close()
    bar = None
    sub: Submission | None = existing
    new_rows = 0
    status, reason, trace = "failed", "", ""
    child_ends = False  # the child said done or error and exits by itself
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
                    status, child_ends = "complete", True
                    break
                elif kind == "error":
                    reason, trace, child_ends = msg[1], msg[2], True
                    break
            elif not proc.is_alive():
                if parent_conn.poll():
                    continue  # drain what it sent before dying
                reason = _death_reason(proc.exitcode, memory_mb)
                break
    finally:
        if bar:
            bar.close()
        if child_ends:
            proc.join(30)  # it has shut its workers down; let it exit cleanly
        _stop(proc)
        parent_conn.close()
    if sub is None:  # the child died before loading the policy
        raise SubmitError(f"the evaluation of {policy!r} could not start: {reason}")
    stored = len(store.done_seeds(sub.id))
    if status == "complete" and stored < len(tr.test_seeds):
        status, reason = "failed", f"only {stored} of {len(tr.test_seeds)} seeds were stored"
    store.set_status(sub.id, status, reason)
    return Outcome(store.find(tr.name, name), status, reason, new_rows, stored,  # type: ignore[arg-type]
                   time.perf_counter() - t0, trace)


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
