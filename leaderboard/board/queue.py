"""The job queue in the board's database: claims with a lease, heartbeats, and fenced writes.

A worker :func:`claim` s a job (queued, or running with an expired lease), which raises the job's
``fence``; every later write (:func:`heartbeat`, :func:`write_rows`, :func:`finish`) first updates
the job's row where the fence is still the claim's, so a worker back after its lease is refused
(:class:`LeaseLost`) before it writes. The next holder runs only the missing units. Claims are
exclusive through ``FOR UPDATE SKIP LOCKED`` (PostgreSQL) or ``BEGIN IMMEDIATE`` (SQLite); leases
use the database's clock. :func:`release` hands back a job the board failed; ``spent_s`` feeds
the upload's time budget. ``docs/leaderboard.md``, "The queue" and "Whose fault a failure is".
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import Connection, Engine
from wfbench.leaderboard.board.db import (
    BOARD_FAULT,
    FAILURE_KINDS,
    LOST,
    MAX_ATTEMPTS,
    ROW_FIELDS,
    cap_log,
    is_sqlite,
    jobs,
    kind_of_reason,
    rows,
    submissions,
)
from wfbench.leaderboard.rows import KPI_COLUMNS

DEFAULT_LEASE_S = 60.0
FINAL_STATES = ("done", "failed")


class LeaseLost(Exception):
    """The claim's lease was taken over by another worker (its fence is stale): nothing was written."""


@dataclass(frozen=True)
class Claim:
    """A worker's hold on one job, valid while the job's fence is still :attr:`fence`."""

    submission_id: int
    worker_id: str
    fence: int
    lease_s: float
    attempt: int  # this claim's number among the submission's attempts, from 1
    engine: Engine = field(repr=False, compare=False)
    spent_s: float = 0.0  # the worker seconds the submission had used before this claim
    max_attempts: int = MAX_ATTEMPTS


def db_now(conn: Connection) -> float:
    """Epoch seconds on the database's clock (PostgreSQL), or this host's (SQLite: the file is local)."""
    if is_sqlite(conn.engine):
        return time.time()
    return float(conn.execute(sa.text("SELECT extract(epoch FROM clock_timestamp())")).scalar())


def claim(engine: Engine, worker_id: str, lease_s: float = DEFAULT_LEASE_S,
          max_attempts: int = MAX_ATTEMPTS, submission_id: int | None = None) -> Claim | None:
    """Take the oldest job that is queued or whose lease expired, or None when there is none.

    A job whose lease expired after ``max_attempts`` claims is failed instead ("lost its
    worker N times") and the next candidate is tried, in the same transaction.
    ``submission_id``: only that submission's job is a candidate.
    """
    if not lease_s > 0:
        raise ValueError(f"lease {lease_s:g} s is not allowed; allowed: seconds > 0")
    with engine.begin() as conn:
        while True:
            now = db_now(conn)
            claimable = (jobs.c.state == "queued") | ((jobs.c.state == "running") & (jobs.c.lease_until < now))
            if submission_id is not None:
                claimable = claimable & (jobs.c.submission_id == submission_id)
            job = conn.execute(
                sa.select(jobs.c.submission_id, jobs.c.state, jobs.c.fence).where(claimable)
                .order_by(jobs.c.submission_id).limit(1).with_for_update(skip_locked=True)).first()
            if job is None:
                return None
            attempts, spent = conn.execute(sa.select(submissions.c.attempts, submissions.c.spent_s)
                                           .where(submissions.c.id == job.submission_id)).one()
            if job.state == "running" and attempts >= max_attempts:
                reason = (f"{LOST} {attempts} times (the worker died or stalled past its lease each time); submit "
                          "the same package again to queue it again")
                conn.execute(jobs.update().where(jobs.c.submission_id == job.submission_id)
                             .values(state="failed", lease_until=None))
                conn.execute(submissions.update().where(submissions.c.id == job.submission_id)
                             .values(state="failed", reason=reason, fault="board", kind=BOARD_FAULT, updated=now))
                continue
            conn.execute(jobs.update().where(jobs.c.submission_id == job.submission_id).values(
                state="running", lease_owner=worker_id, lease_until=now + lease_s, fence=job.fence + 1,
                heartbeat_at=now))
            conn.execute(submissions.update().where(submissions.c.id == job.submission_id).values(
                state="running", attempts=attempts + 1, updated=now))
            return Claim(job.submission_id, worker_id, job.fence + 1, float(lease_s), attempts + 1, engine,
                         float(spent or 0.0), max_attempts)


def _fenced(conn: Connection, c: Claim, spent_s: float | None = None) -> float:
    """Extend the claim's lease if its fence is still current (inside the caller's transaction); else LeaseLost.

    ``spent_s``: the worker seconds the submission has used so far, stored with it.
    """
    now = db_now(conn)
    n = conn.execute(jobs.update().where((jobs.c.submission_id == c.submission_id) & (jobs.c.fence == c.fence)
                                         & (jobs.c.state == "running"))
                     .values(heartbeat_at=now, lease_until=now + c.lease_s)).rowcount
    if n != 1:
        raise LeaseLost(f"submission {c.submission_id}: worker {c.worker_id} lost its lease (fence {c.fence} is "
                        "stale: another worker claimed the job, or its owner withdrew it); nothing was written")
    if spent_s is not None:
        conn.execute(submissions.update().where(submissions.c.id == c.submission_id).values(spent_s=float(spent_s)))
    return now


def heartbeat(c: Claim, spent_s: float | None = None) -> bool:
    """Extend the lease by ``lease_s`` from now (and store ``spent_s``); False when the lease was lost."""
    try:
        with c.engine.begin() as conn:
            _fenced(conn, c, spent_s)
        return True
    except LeaseLost:
        return False


def release(c: Claim, reason: str, spent_s: float | None = None) -> str:
    """Hand a job back after a fault of the board's (not the policy's): ``queued`` again, or ``failed``.

    The job is queued at once for the next worker, with the rows stored so far kept and
    ``reason`` kept beside it (the submission shows a note). At the claim's
    ``max_attempts``-th attempt it fails instead, as the board's fault ("board fault N
    times: ..."), which runs again when its owner submits the same bytes.

    Raises:
        LeaseLost: the fence is stale; nothing was changed.
    """
    line = " ".join(reason.split())
    with c.engine.begin() as conn:
        now = _fenced(conn, c, spent_s)
        if c.attempt >= c.max_attempts:
            conn.execute(jobs.update().where(jobs.c.submission_id == c.submission_id)
                         .values(state="failed", lease_until=None))
            conn.execute(submissions.update().where(submissions.c.id == c.submission_id).values(
                state="failed", fault="board", kind=BOARD_FAULT, updated=now,
                reason=f"{BOARD_FAULT} {c.attempt} times: {line}; submit the same package again to queue it again"))
            return "failed"
        conn.execute(jobs.update().where(jobs.c.submission_id == c.submission_id)
                     .values(state="queued", lease_owner=None, lease_until=None))
        conn.execute(submissions.update().where(submissions.c.id == c.submission_id).values(
            state="queued", fault="board", kind=BOARD_FAULT, reason=line, updated=now))
        return "requeued"


def write_rows(c: Claim, new_rows: Iterable[Mapping[str, Any]], spent_s: float | None = None,
               then: Callable[[Connection, list[dict[str, Any]]], None] | None = None) -> int:
    """Store finished units in one transaction, after checking the fence; returns how many rows were new.

    Each row has the keys of :data:`wfbench.leaderboard.board.db.ROW_FIELDS`; a missing or
    non-finite budget measurement is stored as NULL. A unit already stored is skipped.
    ``then(conn, rows)``: called in the same transaction with the rows inserted, as stored
    (the local board adds their provenance).

    Raises:
        LeaseLost: the fence is stale; nothing was written.
        ValueError: a row with a non-finite KPI (nothing was written).
    """
    values = [_row(c.submission_id, r) for r in new_rows]
    dialect = postgresql if c.engine.dialect.name == "postgresql" else sqlite
    with c.engine.begin() as conn:
        now = _fenced(conn, c, spent_s)
        if not values:
            return 0
        for v in values:
            v["finished"] = now
        # RETURNING counts what was inserted (psycopg reports no rowcount for ON CONFLICT DO NOTHING)
        stmt = dialect.insert(rows).values(values).on_conflict_do_nothing(
            index_elements=[rows.c.submission_id, rows.c.scenario, rows.c.seed_index]).returning(
            rows.c.scenario, rows.c.seed_index)
        inserted = {(r.scenario, r.seed_index) for r in conn.execute(stmt)}
        if then is not None and inserted:
            then(conn, [v for v in values if (v["scenario"], v["seed_index"]) in inserted])
        return len(inserted)


def _row(submission_id: int, r: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {"submission_id": submission_id}
    for k in ROW_FIELDS:
        v = r.get(k)
        if k in KPI_COLUMNS:
            if v is None or not math.isfinite(float(v)):
                raise ValueError(f"scenario {r.get('scenario')!r}, seed index {r.get('seed_index')}: non-finite {k} "
                                 f"({v!r}); no row was stored")
            v = float(v)
        elif k in ("scenario", "machine"):
            v = str(v or "") if k == "scenario" else (str(v) if v else None)
        elif k in ("seed_index", "seed", "episode_length", "invalid_actions"):
            v = int(v)  # type: ignore[arg-type]
        else:  # a budget measurement
            v = float(v) if v is not None and math.isfinite(float(v)) else None
        out[k] = v
    return out


def finish(c: Claim, state: str, reason: str = "", result: Mapping[str, Any] | None = None,
           log: str | None = None, kind: str = "", spent_s: float | None = None) -> None:
    """End the job as ``done`` or ``failed`` (with a one-line ``reason``), storing the aggregate and the log.

    A failure ended here is the policy's own, final: ``kind`` is its word of
    :data:`~wfbench.leaderboard.board.db.FAILURE_KINDS` (default: read from the reason).
    A fault of the board's goes through :func:`release` instead.

    Raises:
        LeaseLost: the fence is stale; nothing was changed.
    """
    if state not in FINAL_STATES:
        raise ValueError(f"final state {state!r} is not allowed; allowed: {', '.join(FINAL_STATES)}")
    line = " ".join(reason.split()) if state == "failed" else ""
    if state == "failed":
        kind = kind or kind_of_reason(line)
        if kind not in FAILURE_KINDS:
            raise ValueError(f"failure kind {kind!r} is not allowed; allowed: {', '.join(FAILURE_KINDS)}")
    values: dict[str, Any] = {"state": state, "reason": line,
                              "result": json.dumps(result, sort_keys=True) if result is not None else None,
                              "fault": "policy" if state == "failed" else "", "kind": kind if state == "failed" else ""}
    if log is not None:
        values["log"] = cap_log(log)
    with c.engine.begin() as conn:
        now = _fenced(conn, c, spent_s)
        conn.execute(jobs.update().where(jobs.c.submission_id == c.submission_id)
                     .values(state=state, lease_until=None))
        conn.execute(submissions.update().where(submissions.c.id == c.submission_id).values(updated=now, **values))
