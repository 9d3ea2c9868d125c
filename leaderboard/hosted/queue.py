"""The job queue in the board's database: claims with a lease, heartbeats, and fenced writes.

A worker :func:`claim` s a job: a queued one, or a running one whose lease expired (its
worker died or stalled). Each claim adds one to the job's ``fence`` and to the
submission's ``attempts``; the claim remembers the fence it got. Every later write of
that worker, :func:`heartbeat` (extend the lease), :func:`write_rows` and :func:`finish`,
runs in one transaction that first updates the job's row *where the fence is still the
claim's*. When another worker has claimed the job since (the first one was paused past
its lease, or its heartbeats did not get through), that update matches nothing and the
write is refused (:class:`LeaseLost`) before anything is written: a worker that comes
back after its lease cannot write. Rows already written by an earlier holder stay (they
are the same rows a clean run makes: the evaluation of a unit does not depend on who runs
it), and the next holder runs only the missing (scenario, seed index) units, so a job is
never lost and no row is written twice (the table's unique key refuses a duplicate in any
case, and an insert skips one).

How a claim stays exclusive: on PostgreSQL the candidate job row is taken with ``SELECT
... FOR UPDATE SKIP LOCKED`` (concurrent claimers skip a row another is claiming instead
of waiting on it, and never both take it), and the fenced update of a write locks the
job's row, so a claim and a write of the same job are serialized. On SQLite every
transaction is ``BEGIN IMMEDIATE`` (:func:`wfbench.leaderboard.hosted.db.connect`): one
writer at a time does the same.

Leases are measured on the database's clock where there is one (PostgreSQL's
``clock_timestamp()``), so workers on hosts whose clocks differ agree on when a lease
ends. A job whose lease expired after ``max_attempts`` claims is not claimed again: it
is failed with the reason "lost its worker 3 times" (a policy that kills its worker
every time must not keep the queue busy forever).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import Connection, Engine
from wfbench.leaderboard.hosted.db import LOST, MAX_ATTEMPTS, ROW_FIELDS, cap_log, is_sqlite, jobs, rows, submissions
from wfbench.leaderboard.store import KPI_COLUMNS

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


def db_now(conn: Connection) -> float:
    """Epoch seconds on the database's clock (PostgreSQL), or this host's (SQLite: the file is local)."""
    if is_sqlite(conn.engine):
        return time.time()
    return float(conn.execute(sa.text("SELECT extract(epoch FROM clock_timestamp())")).scalar())


def claim(engine: Engine, worker_id: str, lease_s: float = DEFAULT_LEASE_S,
          max_attempts: int = MAX_ATTEMPTS) -> Claim | None:
    """Take the oldest job that is queued or whose lease expired, or None when there is none.

    A job whose lease expired after ``max_attempts`` claims is failed instead ("lost its
    worker N times") and the next candidate is tried, in the same transaction.
    """
    if not lease_s > 0:
        raise ValueError(f"lease {lease_s:g} s is not allowed; allowed: seconds > 0")
    with engine.begin() as conn:
        while True:
            now = db_now(conn)
            job = conn.execute(
                sa.select(jobs.c.submission_id, jobs.c.state, jobs.c.fence)
                .where((jobs.c.state == "queued") | ((jobs.c.state == "running") & (jobs.c.lease_until < now)))
                .order_by(jobs.c.submission_id).limit(1).with_for_update(skip_locked=True)).first()
            if job is None:
                return None
            attempts = conn.execute(sa.select(submissions.c.attempts)
                                    .where(submissions.c.id == job.submission_id)).scalar_one()
            if job.state == "running" and attempts >= max_attempts:
                reason = (f"{LOST} {attempts} times (the worker died or stalled past its lease each time); submit "
                          "the same package again to queue it again")
                conn.execute(jobs.update().where(jobs.c.submission_id == job.submission_id)
                             .values(state="failed", lease_until=None))
                conn.execute(submissions.update().where(submissions.c.id == job.submission_id)
                             .values(state="failed", reason=reason, updated=now))
                continue
            conn.execute(jobs.update().where(jobs.c.submission_id == job.submission_id).values(
                state="running", lease_owner=worker_id, lease_until=now + lease_s, fence=job.fence + 1,
                heartbeat_at=now))
            conn.execute(submissions.update().where(submissions.c.id == job.submission_id).values(
                state="running", attempts=attempts + 1, updated=now))
            return Claim(job.submission_id, worker_id, job.fence + 1, float(lease_s), attempts + 1, engine)


def _fenced(conn: Connection, c: Claim) -> float:
    """Extend the claim's lease if its fence is still current (inside the caller's transaction); else LeaseLost."""
    now = db_now(conn)
    n = conn.execute(jobs.update().where((jobs.c.submission_id == c.submission_id) & (jobs.c.fence == c.fence)
                                         & (jobs.c.state == "running"))
                     .values(heartbeat_at=now, lease_until=now + c.lease_s)).rowcount
    if n != 1:
        raise LeaseLost(f"submission {c.submission_id}: worker {c.worker_id} lost its lease (fence {c.fence} is "
                        "stale: another worker claimed the job); nothing was written")
    return now


def heartbeat(c: Claim) -> bool:
    """Extend the lease by ``lease_s`` from now; False when the lease was lost (another worker holds the job)."""
    try:
        with c.engine.begin() as conn:
            _fenced(conn, c)
        return True
    except LeaseLost:
        return False


def write_rows(c: Claim, new_rows: Iterable[Mapping[str, Any]]) -> int:
    """Store finished units in one transaction, after checking the fence; returns how many rows were new.

    Each row has the keys of :data:`wfbench.leaderboard.hosted.db.ROW_FIELDS`; a missing or
    non-finite budget measurement is stored as NULL. A unit already stored is skipped.

    Raises:
        LeaseLost: the fence is stale; nothing was written.
        ValueError: a row with a non-finite KPI (nothing was written).
    """
    values = [_row(c.submission_id, r) for r in new_rows]
    dialect = postgresql if c.engine.dialect.name == "postgresql" else sqlite
    with c.engine.begin() as conn:
        now = _fenced(conn, c)
        if not values:
            return 0
        for v in values:
            v["finished"] = now
        # RETURNING counts what was inserted (psycopg reports no rowcount for ON CONFLICT DO NOTHING)
        stmt = dialect.insert(rows).values(values).on_conflict_do_nothing(
            index_elements=[rows.c.submission_id, rows.c.scenario, rows.c.seed_index]).returning(rows.c.seed_index)
        return len(conn.execute(stmt).all())


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
           log: str | None = None) -> None:
    """End the job as ``done`` or ``failed`` (with a one-line ``reason``), storing the aggregate and the log.

    Raises:
        LeaseLost: the fence is stale; nothing was changed.
    """
    if state not in FINAL_STATES:
        raise ValueError(f"final state {state!r} is not allowed; allowed: {', '.join(FINAL_STATES)}")
    line = " ".join(reason.split()) if state == "failed" else ""
    values: dict[str, Any] = {"state": state, "reason": line,
                              "result": json.dumps(result, sort_keys=True) if result is not None else None}
    if log is not None:
        values["log"] = cap_log(log)
    with c.engine.begin() as conn:
        now = _fenced(conn, c)
        conn.execute(jobs.update().where(jobs.c.submission_id == c.submission_id)
                     .values(state=state, lease_until=None))
        conn.execute(submissions.update().where(submissions.c.id == c.submission_id).values(updated=now, **values))
