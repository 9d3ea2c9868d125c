"""Submit a policy to a track of the local board: a job in its queue, run at once by an in-process worker.

:func:`submit` checks the submission, loads the policy in its child
(:class:`~wfbench.leaderboard.local.LocalRunner`), opens the entry by its fingerprint (the same
one resumes, another is refused unless ``replace``), queues its job and runs it with the hosted
board's :class:`~wfbench.leaderboard.board.worker.Worker`, which commits each finished chunk at
once. A policy that cannot be loaded is a user error (nothing stored); any other failure marks
the entry ``failed`` with a one-line reason and leaves every stored row as it was.
``docs/leaderboard.md``, "Submitting" and "One board".
"""

from __future__ import annotations

import getpass
import json
import os
import time
from dataclasses import dataclass, field
from typing import Any

import sqlalchemy as sa
from wfbench.leaderboard.board.db import Submission
from wfbench.leaderboard.board.worker import Worker
from wfbench.leaderboard.fingerprint import fingerprint_change, is_entry_point, policy_fingerprint
from wfbench.leaderboard.local import LocalRunner, RemainingTime
from wfbench.leaderboard.rows import NameTaken, SubmitError
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.tracks import Track, get_track
from wfbench.policies import registry as _registry

from wfbench import __version__
from wfbench.harness.backends import Execution, check_execution
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, PolicyLoadError, check_act_timeout, load_policy

__all__ = ["SubmitError", "Outcome", "RemainingTime", "submit", "describe", "scenario_times", "seed_builtins",
           "seed_tracks", "is_entry_point", "policy_fingerprint", "fingerprint_change"]

DEFAULT_WALL_TIME_S = 3600.0
DEFAULT_MEMORY_MB = 8192
STORED_CHUNK = 5  # seeds per stored chunk where the Execution names no chunk size
DEFAULT_EXECUTION = Execution(backend="process")
BUILTIN_ENTRIES = _registry.LINEUPS["leaderboard"]  # the entries seed_builtins makes (the registry's lineups)


@dataclass(frozen=True)
class Outcome:
    submission: Submission
    status: str  # complete | failed
    reason: str  # one line; empty when complete
    new_rows: int
    stored_rows: int
    seconds: float
    trace: str = ""  # the failure's whole traceback, formatted in the child (for --traceback)
    action: str = "resumed"  # new | resumed | replaced | legacy (Store.open_submission)
    # CPU seconds of this run's episodes per scenario ("" on a single-scenario track), as the rows report them
    scenario_seconds: dict[str, float] = field(default_factory=dict)


def submit(track: str | Track, policy: str, name: str, submitter: str | None = None, db: Any = None,
           execution: Execution = DEFAULT_EXECUTION, wall_time_s: float = DEFAULT_WALL_TIME_S,
           memory_mb: int | None = DEFAULT_MEMORY_MB, builtin: bool = False,
           act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S, replace: bool = False) -> Outcome:
    """Evaluate ``policy`` (a registry name or ``module:attr``) on the track's test seeds and store the rows.

    The entry's job goes into the local board's queue and an in-process
    :class:`~wfbench.leaderboard.board.worker.Worker` runs it at once with a
    :class:`~wfbench.leaderboard.local.LocalRunner` (the policy in a child process, no
    sandbox). The policy runs on every scenario of the track, one row per (scenario, seed).

    Args:
        track: a track name or :class:`~wfbench.leaderboard.tracks.Track`.
        policy: a registry name or a ``module:attr`` entry point.
        name: the entry's name on the track; submitting it again resumes.
        submitter: who submits (default: the user name).
        db: a store path or :class:`~wfbench.leaderboard.store.Store` (default: the user's store).
        execution: where the child runs the episodes, and its progress bar
            (:class:`~wfbench.harness.backends.Execution`); its ``chunk_size`` is the seeds per
            stored chunk (``None``: 5). Default: a pool of processes over all cores.
        wall_time_s: the whole evaluation's limit in seconds.
        memory_mb: the child's address-space limit in MiB (``None``: none).
        builtin: mark the entry as one of wfbench's own.
        act_timeout_s: limit of each ``reset``/``act`` call of a user's policy in
            seconds; ``None`` or 0 for none.
        replace: when the name is taken, move its entry to the audit tables and
            evaluate every seed anew (whatever the fingerprints).

    Returns:
        The outcome: ``complete``, or ``failed`` with a one-line reason and its trace.

    Raises:
        SubmitError: the submission cannot start (unknown track or policy, a policy that
            cannot be loaded, a name taken by another fingerprint without ``replace``,
            bad limits); nothing is stored.
    """
    try:
        tr = track if isinstance(track, Track) else get_track(track)
        execution = check_execution(execution)
        if execution.chunk_size is None:
            execution = execution.replace(chunk_size=STORED_CHUNK)
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
    fingerprint, detail = (None, None) if is_entry_point(policy) else policy_fingerprint(policy)
    store = db if isinstance(db, Store) else Store(db)
    t0 = time.perf_counter()
    existing = store.find(tr.name, name)
    if existing is not None and fingerprint is not None and not replace and not existing.legacy:
        _check_taken(existing, tr, name, policy, fingerprint, detail)  # no child needed to refuse
        done = store.done_units(existing.id)
        if all(u in done for u in tr.units()):  # nothing to evaluate, and no user code to load
            if existing.status != "complete":
                store.set_status(existing.id, "done", "")
            sub = store.find(tr.name, name)
            return Outcome(sub, "complete", "", 0, len(done), time.perf_counter() - t0)  # type: ignore[arg-type]
    with LocalRunner(tr, policy, execution, wall_time_s, memory_mb, act_timeout_s) as runner:
        if fingerprint is None:
            fingerprint, detail = runner.fingerprint, runner.detail
        try:
            sub, action = store.open_submission(
                tr, name, policy, submitter, __version__, builtin=builtin, fingerprint=fingerprint,
                fingerprint_detail=json.dumps(detail, sort_keys=True), replace=replace,
                budget=json.dumps(runner.budget, sort_keys=True))
        except NameTaken as exc:
            _check_taken(exc.existing, tr, name, policy, fingerprint, detail)
            raise
        runner.entry = sub
        store.board.tracks[tr.name] = tr  # the local board runs whatever track its caller names
        before = len(store.done_units(sub.id))
        worker = Worker(store.board, f"local:{os.getpid()}", runner=runner, say=lambda line: None)
        try:
            state = worker.run_one(sub.id)
        except sa.exc.OperationalError as exc:
            raise store.write_error(f"the results of {name!r}", exc) from None
    stored = len(store.done_units(sub.id))
    end = store.find(tr.name, name)
    if state == "done":
        status, reason, trace = "complete", "", ""
    elif runner.failure is not None:
        status, reason, trace = "failed", runner.failure.message, runner.failure.trace
    else:  # the job failed elsewhere (its rows did not fit the track) or was taken over
        status, trace = "failed", ""
        reason = end.reason if end is not None and end.reason else f"its job ended {state}"
    return Outcome(end or sub, status, reason, stored - before, stored, time.perf_counter() - t0, trace,
                   action, runner.clock.per_scenario() if runner.clock is not None else {})


def _check_taken(existing: Submission, tr: Track, name: str, policy: str, fingerprint: str,
                 detail: dict[str, Any] | None) -> None:
    """Raise the one-line SubmitError when ``name`` is taken by another fingerprint or track version."""
    how = ("pass --replace to evaluate this policy under that name (the old entry's rows are kept in the store's "
           "audit tables) or choose another --name")
    if existing.fingerprint != fingerprint:
        change = fingerprint_change(existing.fingerprint_detail, detail or {})
        raise SubmitError(f"the name {name!r} on track {tr.name} is taken by a different policy ({existing.entry!r}, "
                          f"fingerprint {existing.fingerprint}; now {policy!r}, fingerprint {fingerprint}: {change}); "
                          f"{how}")
    if existing.track_hash != tr.hash:
        raise SubmitError(f"the entry {name!r} was made on another version of track {tr.name} (hash "
                          f"{existing.track_hash}, now {tr.hash}); {how}")


def scenario_times(out: Outcome) -> str:
    """One line: the CPU seconds this run spent per scenario, costliest first ("" on a single-scenario track)."""
    times = {sc: t for sc, t in out.scenario_seconds.items() if sc}
    if not times:
        return ""
    parts = ", ".join(f"{sc} {t:.3g}" for sc, t in sorted(times.items(), key=lambda kv: (-kv[1], kv[0])))
    return f"CPU seconds per scenario (this run's episodes, costliest first): {parts}"


def seed_tracks(track: str | Track | None = None) -> list[Track]:
    """The tracks ``wfbench leaderboard baselines`` fills: the one named, or every track marked ``seeded``.

    A track that runs a whole suite is not marked (:func:`~wfbench.leaderboard.tracks.suite_track`): named only.
    """
    from wfbench.leaderboard.tracks import TRACKS

    if track is not None:
        return [track if isinstance(track, Track) else get_track(track)]
    return [t for t in TRACKS.values() if t.seeded]


MOVED = {"replaced": "; the entry it replaced is in the audit tables",
         "legacy": "; its rows stored without a fingerprint (an older wfbench) are in the audit tables"}
"""What :func:`describe` adds for a submission that moved an entry to the audit tables, by ``Outcome.action``."""


def describe(out: Outcome, track: Track, store_path: Any, hint: str = "") -> str:
    """The line ``wfbench leaderboard submit`` prints for a submission's outcome.

    A complete one says how many rows it stored and, where it replaced an entry or a
    legacy one, that the old rows are in the audit tables (:data:`MOVED`); a failed one
    says why and that its rows are kept for a resume. ``hint`` ends the failure's note.
    """
    what = track.unit_word
    name = out.submission.name
    if out.status == "complete":
        return (f"{name} on {track.name}: complete, {out.stored_rows} {what} stored ({out.new_rows} new) "
                f"in {store_path}, {out.seconds:.1f} s{MOVED.get(out.action, '')}")
    return (f"submission {name!r} on {track.name} failed: {out.reason} ({out.stored_rows} {what} kept in "
            f"{store_path}; submit again to resume, or with --replace once the policy is changed{hint})")


def seed_builtins(track: str | Track, db: Any = None, names: tuple[str, ...] = BUILTIN_ENTRIES,
                  execution: Execution = DEFAULT_EXECUTION, **kwargs: Any) -> list[Outcome]:
    """Submit (or resume) the built-in policies under their registry names.

    A built-in entry whose fingerprint is not the current code's (wfbench's policy code
    changed since it was stored) is replaced: its rows go to the audit tables. ``execution``
    and ``kwargs`` (``wall_time_s``, ``memory_mb``) are :func:`submit`'s.
    """
    tr = track if isinstance(track, Track) else get_track(track)
    store = db if isinstance(db, Store) else Store(db)
    out = []
    for n in names:
        existing = store.find(tr.name, n)
        stale = existing is not None and not existing.legacy and (
            existing.fingerprint != policy_fingerprint(n)[0] or existing.track_hash != tr.hash)
        out.append(submit(tr, n, n, submitter="wfbench", db=store, builtin=True, execution=execution,
                          replace=stale, **kwargs))
    return out
