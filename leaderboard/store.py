"""The local leaderboard: the hosted board's database (:class:`~wfbench.leaderboard.board.db.Board`) on a SQLite file.

An entry is a test-phase submission of the board (its policy spec the entry point, its
submitter the account, its seeds the track's published test seeds, ``seed_index`` the
seed itself); what the local board adds to the hosted schema stands in two tables of
its own: ``local_entries`` (fingerprint, budget, built-in, and, for an entry off the
board, why it left) and ``local_rows`` (each row's provenance and digest). Replacing or
withdrawing an entry withdraws its submission: its rows stay, and :meth:`Store.audit`
lists them. A store of schema 4 (the sqlite3 file of earlier versions) is imported once
when opened, its file kept beside as ``NAME.schema4``. docs/leaderboard.md#one-board.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import sqlite3
import time
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd
import sqlalchemy as sa
from sqlalchemy.engine import Connection
from wfbench.leaderboard import report
from wfbench.leaderboard.board import db as board_db
from wfbench.leaderboard.board.db import Board, accounts, kind_of_reason, packages, submissions
from wfbench.leaderboard.board.migrations import NewerBoardError, check_known
from wfbench.leaderboard.rows import (
    BUDGET_ROW_COLUMNS,
    KPI_COLUMNS,
    RESULT_FRAME_COLUMNS,
    ROW_COLUMNS,
    Entry,
    NameTaken,
    StoreError,
    budget_value,
    check_rows,
    default_path,
    row_digest,
    scrub_paths,
)
from wfbench.leaderboard.schema4 import Schema4Store, is_schema4
from wfbench.leaderboard.tracks import Track, get_track

from wfbench.core.kpis import SCORE
from wfbench.harness.budget import BUDGET_COLUMNS

__all__ = ["KPI_COLUMNS", "ROW_COLUMNS", "BUDGET_ROW_COLUMNS", "Entry", "NameTaken", "Store", "StoreError", "Shown",
           "default_path", "row_digest", "scrub_paths", "show"]

APPLICATION_ID = 0x57464232  # "WFB2": a local board (a schema-4 store is "WFB1")
PHASE = "test"  # a local entry runs the track's published test seeds
_STATE = {"running": "running", "complete": "done", "failed": "failed"}  # local status -> the board's state
_STATUS = {"queued": "running", "running": "running", "done": "complete", "failed": "failed"}

local_metadata = sa.MetaData()
local_entries = sa.Table(
    "local_entries", local_metadata,
    sa.Column("submission_id", sa.Integer, sa.ForeignKey(submissions.c.id), primary_key=True),
    sa.Column("builtin", sa.Boolean, nullable=False),
    sa.Column("fingerprint", sa.String(16), nullable=False),  # "": a legacy entry, stored before fingerprints
    sa.Column("fingerprint_detail", sa.Text, nullable=False),
    sa.Column("budget", sa.Text, nullable=False),  # JSON: what the policy states about its cost; "": not recorded
    sa.Column("wfbench_version", sa.String(40), nullable=False),
    sa.Column("created_at", sa.String(40), nullable=False),
    # once the entry is off the board (its submission withdrawn): replaced or withdrawn, why, when, in what order
    sa.Column("action", sa.String(10), nullable=False, default=""),
    sa.Column("note", sa.Text, nullable=False, default=""),
    sa.Column("moved_at", sa.String(40), nullable=False, default=""),
    sa.Column("audit_id", sa.Integer, nullable=True),
)
local_rows = sa.Table(
    "local_rows", local_metadata,
    sa.Column("submission_id", sa.Integer, sa.ForeignKey(submissions.c.id), nullable=False),
    sa.Column("scenario", sa.String(100), nullable=False),
    sa.Column("seed_index", sa.BigInteger, nullable=False),
    sa.Column("track", sa.String(100), nullable=False),
    sa.Column("track_hash", sa.String(64), nullable=False),
    sa.Column("policy", sa.String(300), nullable=False),
    sa.Column("submitter", sa.String(100), nullable=False),
    sa.Column("fingerprint", sa.String(16), nullable=False),
    sa.Column("wfbench_version", sa.String(40), nullable=False),
    sa.Column("finished_at", sa.String(40), nullable=False),
    sa.Column("digest", sa.String(64), nullable=False),
    sa.UniqueConstraint("submission_id", "scenario", "seed_index", name="one_local_row_per_unit"),
)
_ENTRY_FIELDS = ("builtin", "fingerprint", "fingerprint_detail", "budget")
_PROVENANCE = ("track", "track_hash", "policy", "submitter", "fingerprint", "wfbench_version", "finished_at", "digest")


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _epoch(text: str) -> float:
    try:
        return datetime.fromisoformat(text).timestamp()
    except (TypeError, ValueError):
        return 0.0


_ENTRY_QUERY = (sa.select(submissions, accounts.c.name.label("account"), *(local_entries.c[c] for c in (
    *_ENTRY_FIELDS, "wfbench_version", "created_at", "action", "note", "moved_at", "audit_id")))
    .join(accounts, accounts.c.id == submissions.c.account_id)
    .join(local_entries, local_entries.c.submission_id == submissions.c.id))
_ON_BOARD = submissions.c.withdrawn.is_(None)


def _entry(r: Any) -> Entry:
    return Entry(r["id"], r["track"], r["name"], r["entry"], r["account"], r["track_hash"], _STATUS[r["state"]],
                 r["reason"], bool(r["builtin"]), r["fingerprint"], r["fingerprint_detail"], r["budget"])


class Store:
    """The local board at ``path``.

    Args:
        path: the board's file (default: :func:`~wfbench.leaderboard.rows.default_path`).
        create: make the board when the file does not exist (writers do); readers pass
            ``False`` and get a StoreError saying the file does not exist.
    """

    def __init__(self, path: str | os.PathLike | None = None, create: bool = True):
        self.path = Path(path) if path is not None else default_path()
        self.imported_from: Path | None = None  # the schema-4 file this open imported, kept as it was
        if self.path.exists():
            schema4 = self._check_file()
        elif not create:
            raise StoreError(f"store {self.path} does not exist; pass --db with the file that "
                             "'wfbench leaderboard submit' or 'seed' wrote, or run one of them first")
        else:
            schema4 = False
            if self.path.parent.exists() and not self.path.parent.is_dir():
                raise StoreError(f"cannot create store {self.path}: {self.path.parent} is not a folder")
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise StoreError(f"cannot create store {self.path}: {exc.strerror or exc}") from None
        if schema4:
            self._import()
        else:
            self.board = self._open_board()

    # -- opening -----------------------------------------------------------------------------------
    def _check_file(self) -> bool:
        """Refuse a file that is not a board; True for a schema-4 store (to import), False for a board or empty file."""
        if self.path.is_dir():
            raise StoreError(f"{self.path} is a folder, not a wfbench store file")
        try:
            with open(self.path, "rb") as fh:
                head = fh.read(16)
        except OSError as exc:
            raise StoreError(f"cannot read store {self.path}: {exc.strerror or exc}") from None
        if head and head != b"SQLite format 3\x00":
            raise StoreError(f"{self.path} is not a wfbench store (not an SQLite database); pass --db with another "
                             "path")
        try:
            conn = sqlite3.connect(self.path, timeout=30.0)
            try:
                if is_schema4(conn, self.path):
                    return True
                app = conn.execute("PRAGMA application_id").fetchone()[0]
                tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            finally:
                conn.close()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path} is not a usable wfbench store: {exc}") from None
        if app == APPLICATION_ID and not {"submissions", "local_entries"} <= tables:
            raise StoreError(f"{self.path} is marked as a wfbench store but its tables are missing")
        if app != APPLICATION_ID and tables:
            raise StoreError(f"{self.path} is an SQLite database but not a wfbench store; pass --db with another path")
        return False

    def _open_board(self) -> Board:
        board = Board(self.path)
        try:
            try:
                with board.engine.connect() as conn:
                    check_known(conn)
            except NewerBoardError as exc:
                raise StoreError(f"{self.path} was written by a newer wfbench (board schema {exc.revision}; this "
                                 f"wfbench reads up to {exc.head}): upgrade wfbench to read it") from None
            board.create()
            local_metadata.create_all(board.engine)
            with board.engine.begin() as conn:
                conn.exec_driver_sql(f"PRAGMA application_id={APPLICATION_ID}")
        except sa.exc.OperationalError as exc:
            board.close()
            raise StoreError(f"cannot open store {self.path}: {exc.orig or exc}") from None
        except BaseException:
            board.close()
            raise
        return board

    def _import(self) -> None:
        """Import the schema-4 store at :attr:`path` into a new board there, in one transaction; keep the old file."""
        conn = sqlite3.connect(self.path, timeout=30.0)
        try:  # its rows into the main file (a WAL store), so that the file kept holds them all
            if conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal":
                conn.execute("PRAGMA journal_mode=DELETE")
        except sqlite3.OperationalError as exc:
            raise StoreError(f"cannot import store {self.path}: {exc}; nothing was changed") from None
        finally:
            conn.close()
        old = Schema4Store(self.path)
        try:
            tables = {name: old.table(name, order) for name, order in (
                ("submissions", "id"), ("results", "submission_id, scenario, seed"),
                ("audit_submissions", "audit_id"), ("audit_results", "audit_id, scenario, seed"))}
        finally:
            old.close()
        kept = self.path.with_name(self.path.name + ".schema4")
        n = 1
        while kept.exists():
            kept, n = self.path.with_name(f"{self.path.name}.schema4.{n}"), n + 1
        try:
            os.replace(self.path, kept)
        except OSError as exc:
            raise StoreError(f"cannot import store {self.path}: cannot keep it as {kept.name} "
                             f"({exc.strerror or exc}); nothing was changed") from None
        try:
            self.board = self._open_board()
            self._write(f"the import of {kept}", lambda c: _import_tables(c, tables))
        except BaseException:
            if getattr(self, "board", None) is not None:
                self.board.close()
            for suffix in ("", "-wal", "-shm"):
                Path(f"{self.path}{suffix}").unlink(missing_ok=True)
            os.replace(kept, self.path)
            raise
        self.imported_from = kept

    @property
    def engine(self) -> sa.engine.Engine:
        return self.board.engine

    def close(self) -> None:
        self.board.close()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _write(self, what: str, fn: Any) -> Any:
        try:
            with self.engine.begin() as conn:
                return fn(conn)
        except sa.exc.OperationalError as exc:
            raise self.write_error(what, exc) from None

    def write_error(self, what: str, exc: sa.exc.OperationalError) -> StoreError:
        """The one line for a write of ``what`` the database refused (a full disk: nothing was lost)."""
        text = str(exc.orig or exc)
        if "full" in text:
            return StoreError(f"cannot write {what} to {self.path}: the disk is full ({text}); nothing was lost, "
                              "finished seeds are kept: free space and submit again to resume")
        return StoreError(f"cannot write {what} to {self.path}: {text}")

    # -- entries -----------------------------------------------------------------------------------
    def submissions(self, track: str | None = None) -> list[Entry]:
        """The entries on the board (of ``track``), oldest first."""
        q = _ENTRY_QUERY.where(_ON_BOARD)
        if track:
            q = q.where(submissions.c.track == track)
        with self.engine.begin() as conn:
            return [_entry(r) for r in conn.execute(q.order_by(submissions.c.id)).mappings()]

    def find(self, track: str, name: str) -> Entry | None:
        with self.engine.begin() as conn:
            r = _find(conn, track, name)
        return _entry(r) if r else None

    def open_submission(self, track: Track, name: str, policy: str, submitter: str, version: str,
                        builtin: bool = False, fingerprint: str = "", fingerprint_detail: str = "",
                        replace: bool = False, budget: str = "") -> tuple[Entry, str]:
        """The entry ``name`` of ``track`` for a policy with this fingerprint, its job queued, in one transaction.

        Returns the entry and what happened: ``"new"``, ``"resumed"`` (same fingerprint
        and track version: only missing seeds are to be evaluated), ``"replaced"``
        (``replace``: the old entry left the board, its rows kept for :meth:`audit`) or
        ``"legacy"`` (the old entry had no fingerprint: it left the board, and every seed
        is evaluated anew). ``budget`` (JSON) is what the policy states about its cost.

        Raises:
            NameTaken: the name is taken by another fingerprint or was made on another
                version of the track, and ``replace`` is not set.
        """
        if not name or len(name) > 100 or any(c in name for c in "\n\r\t"):
            raise StoreError(f"submission name {name!r} is not allowed; allowed: 1-100 characters, one line")

        def open_(conn: Connection) -> str:
            r = _find(conn, track.name, name)
            existing = _entry(r) if r else None
            action = "new"
            if existing is not None:
                if replace:
                    _archive(conn, existing.id, "replaced", f"replaced by --replace with fingerprint {fingerprint}")
                    action = "replaced"
                elif existing.legacy:
                    _archive(conn, existing.id, "replaced", "stored without a fingerprint (store schema 1); "
                             f"re-evaluated on resubmission with fingerprint {fingerprint}")
                    action = "legacy"
                elif existing.fingerprint != fingerprint:
                    raise NameTaken(existing, "fingerprint")
                elif existing.track_hash != track.hash:
                    raise NameTaken(existing, "track")
                else:
                    _set_state(conn, existing.id, "running", "")
                    conn.execute(local_entries.update().where(local_entries.c.submission_id == existing.id)
                                 .values(budget=budget))
                    _queue(conn, existing.id)
                    return "resumed"
            _queue(conn, _add_entry(conn, track.name, track.hash, name, policy, submitter, "running", "", {
                "builtin": bool(builtin), "fingerprint": fingerprint, "fingerprint_detail": fingerprint_detail,
                "budget": budget, "wfbench_version": version, "created_at": _now()}))
            return action

        action = self._write(f"submission {name!r}", open_)
        return self.find(track.name, name), action  # type: ignore[return-value]

    def withdraw(self, track: str, name: str, note: str = "") -> int:
        """Take the entry ``name`` off ``track``'s board (its rows kept for :meth:`audit`); returns how many rows.

        Raises:
            StoreError: no entry of that name on the track (the message names those there are).
        """
        def withdraw_(conn: Connection) -> int:
            r = _find(conn, track, name)
            if r is None:
                there = conn.execute(sa.select(submissions.c.name).where((submissions.c.track == track) & _ON_BOARD)
                                     .order_by(submissions.c.id)).scalars().all()
                raise StoreError(f"no entry {name!r} on track {track} in {self.path}; entries there: "
                                 f"{', '.join(there) if there else 'none'}")
            return _archive(conn, r["id"], "withdrawn", note or "withdrawn")

        return self._write(f"the withdrawal of {name!r}", withdraw_)

    def audit(self, track: str | None = None) -> pd.DataFrame:
        """The audit trail: a row per result of an entry off the board (or per such entry without any), oldest first."""
        e, r, p = local_entries, board_db.rows, local_rows
        q = (sa.select(e.c.audit_id, submissions.c.track, submissions.c.name, submissions.c.entry.label("policy"),
                       e.c.fingerprint, submissions.c.state.label("status"), e.c.action, e.c.note, e.c.moved_at,
                       r.c.scenario, r.c.seed, r.c[SCORE], p.c.digest)
             .select_from(e.join(submissions, submissions.c.id == e.c.submission_id)
                          .outerjoin(r, r.c.submission_id == e.c.submission_id)
                          .outerjoin(p, (p.c.submission_id == r.c.submission_id) & (p.c.scenario == r.c.scenario)
                                     & (p.c.seed_index == r.c.seed_index)))
             .where(e.c.audit_id.is_not(None)).order_by(e.c.audit_id, r.c.scenario, r.c.seed))
        if track:
            q = q.where(submissions.c.track == track)
        with self.engine.begin() as conn:
            df = pd.read_sql_query(q, conn)
        return df.assign(status=df["status"].map(_STATUS))

    def set_status(self, sub_id: int, status: str, reason: str = "") -> None:
        self._write("the submission status", lambda c: _set_state(c, sub_id, _STATE[status], reason))

    def done_units(self, sub_id: int) -> set[tuple[str, int]]:
        """The (scenario, seed) pairs stored for an entry (scenario ``""`` on a one-scenario track)."""
        with self.engine.begin() as conn:
            return _done(conn, sub_id)

    def add_results(self, sub: Entry, version: str, rows: Iterable[dict[str, Any]]) -> int:
        """Store finished seeds in one transaction; returns how many were new.

        A row holds the KPIs, ``episode_length`` and ``invalid_actions``, and its budget
        (:data:`~wfbench.leaderboard.rows.BUDGET_ROW_COLUMNS`) when measured: a missing or
        non-finite measurement is stored as NULL. Each row names its ``scenario`` (``""`` on a one-scenario track).
        """
        rows = list(rows)
        for row in rows:
            bad = [c for c in KPI_COLUMNS if not math.isfinite(float(row[c]))]
            if bad:
                raise StoreError(f"seed {row['seed']}: non-finite {', '.join(bad)}; the row was not stored")

        def insert(conn: Connection) -> int:
            done = _done(conn, sub.id)
            new = []
            for row in rows:
                seed, scenario = int(row["seed"]), str(row.get("scenario") or "")
                if (scenario, seed) in done:
                    continue
                budget = {c: None if budget_value(row.get(c)) is None else float(row[c]) for c in BUDGET_COLUMNS}
                new.append({**row, **budget, "machine": row.get("machine") or None, "scenario": scenario,
                            "seed": seed, "seed_index": seed})
                _add_row(conn, sub.id, new[-1], seed, time.time())
                done.add((scenario, seed))
            add_provenance(conn, sub, version, new)
            return len(new)

        return self._write(f"{len(rows)} result(s) of {sub.name!r}", insert)

    # -- reading -----------------------------------------------------------------------------------
    def results(self, track: Track) -> tuple[pd.DataFrame, list[str]]:
        """Valid rows of the track (with the entry's name) and one message per refused row."""
        r, p = board_db.rows, local_rows
        q = (sa.select(submissions.c.name, submissions.c.state, local_entries.c.builtin, r.c.submission_id, r.c.seed,
                       *(p.c[c] for c in _PROVENANCE), *(r.c[c] for c in (*ROW_COLUMNS, *BUDGET_ROW_COLUMNS,
                                                                           "scenario")))
             .select_from(r.join(submissions, submissions.c.id == r.c.submission_id)
                          .join(local_entries, local_entries.c.submission_id == submissions.c.id)
                          .join(p, (p.c.submission_id == r.c.submission_id) & (p.c.scenario == r.c.scenario)
                                & (p.c.seed_index == r.c.seed_index)))
             .where((p.c.track == track.name) & _ON_BOARD).order_by(submissions.c.id, r.c.scenario, r.c.seed))
        with self.engine.begin() as conn:
            found = [{**d, "status": _STATUS[d.pop("state")]} for d in (dict(m) for m in conn.execute(q).mappings())]
        keep, refused = check_rows(found, track)
        return pd.DataFrame(keep, columns=list(RESULT_FRAME_COLUMNS)), refused


# -- writing, inside the caller's transaction ---------------------------------------------------------


def _find(conn: Connection, track: str, name: str) -> Any:
    return conn.execute(_ENTRY_QUERY.where((submissions.c.track == track) & (submissions.c.name == name)
                                           & _ON_BOARD)).mappings().first()


def _done(conn: Connection, sub_id: int) -> set[tuple[str, int]]:
    return {(r.scenario, r.seed) for r in conn.execute(
        sa.select(board_db.rows.c.scenario, board_db.rows.c.seed).where(board_db.rows.c.submission_id == sub_id))}


def _set_state(conn: Connection, sub_id: int, state: str, reason: str) -> None:
    failed = state == "failed"
    conn.execute(submissions.update().where(submissions.c.id == sub_id).values(
        state=state, reason=reason, updated=time.time(), fault="policy" if failed else "",
        kind=kind_of_reason(reason) if failed else ""))


def _account(conn: Connection, name: str) -> int:
    """The id of the account named ``name``, made (with a token nobody holds) on its first entry."""
    found = conn.execute(sa.select(accounts.c.id).where(accounts.c.name == name)).scalar()
    if found is not None:
        return found
    return conn.execute(accounts.insert().values(
        name=name, token_hash=board_db.token_hash(secrets.token_urlsafe(32)), admin=name == board_db.BUILTIN_ACCOUNT,
        created=time.time())).inserted_primary_key[0]


def _add_entry(conn: Connection, track: str, track_hash: str, name: str, policy: str, submitter: str, status: str,
               reason: str, entry: dict[str, Any], withdrawn: float | None = None) -> int:
    """Insert an entry: its submission, its package (the entry's own record) and its ``local_entries`` row."""
    sub_id = (conn.execute(sa.select(sa.func.max(submissions.c.id))).scalar() or 0) + 1
    # a local entry has no package to run: its package is its record, one per entry (the board's key needs one)
    data = json.dumps({"local entry": sub_id, "track": track, "name": name, "policy": policy,
                       "fingerprint": entry["fingerprint"]}, sort_keys=True).encode()
    sha = board_db.package_sha(data)
    now = time.time()
    conn.execute(packages.insert().values(sha256=sha, bytes=data, size=len(data), created=now))
    state = _STATE[status]
    failed = state == "failed"
    conn.execute(submissions.insert().values(
        id=sub_id, account_id=_account(conn, submitter), track=track, track_hash=track_hash, phase=PHASE,
        package_sha=sha, entry=policy, name=name, state=state, reason=reason,
        created=_epoch(entry["created_at"]) or now, updated=now, attempts=0, hidden_version=None, log="",
        result=None, fault="policy" if failed else "", kind=kind_of_reason(reason) if failed else "", spent_s=0.0,
        withdrawn=withdrawn))
    conn.execute(local_entries.insert().values(submission_id=sub_id, **entry))
    return sub_id


def _add_row(conn: Connection, sub_id: int, values: dict[str, Any], seed: int, finished: float,
             provenance: dict[str, Any] | None = None) -> None:
    scenario = values["scenario"]
    conn.execute(board_db.rows.insert().values(
        submission_id=sub_id, scenario=scenario, seed_index=seed, seed=seed, finished=finished,
        **{c: float(values[c]) for c in KPI_COLUMNS}, episode_length=int(values["episode_length"]),
        invalid_actions=int(values["invalid_actions"]), **{c: values.get(c) for c in BUDGET_ROW_COLUMNS}))
    if provenance is not None:
        conn.execute(local_rows.insert().values(submission_id=sub_id, scenario=scenario, seed_index=seed,
                                                **provenance))


def add_provenance(conn: Connection, sub: Entry, version: str, rows: list[dict[str, Any]]) -> None:
    """Each new row's provenance and digest (``local_rows``), inside the caller's transaction.

    ``rows``: as stored in the board's ``rows`` table (the seed is the seed index); the
    local worker's writes (:func:`wfbench.leaderboard.board.queue.write_rows`) call it.
    """
    for values in rows:
        seed = int(values["seed"])
        conn.execute(local_rows.insert().values(
            submission_id=sub.id, scenario=values["scenario"], seed_index=seed, track=sub.track,
            track_hash=sub.track_hash, policy=sub.policy, submitter=sub.submitter, fingerprint=sub.fingerprint,
            wfbench_version=version, finished_at=_now(),
            digest=row_digest(sub.name, sub.track, sub.track_hash, sub.policy, sub.submitter, version, seed, values,
                              sub.fingerprint)))


def _queue(conn: Connection, sub_id: int) -> None:
    """Queue the entry's job for the local worker: a new one, or its old one again (fenced off any earlier run)."""
    values = {"state": "queued", "lease_owner": None, "lease_until": None}
    if conn.execute(board_db.jobs.update().where(board_db.jobs.c.submission_id == sub_id)
                    .values(fence=board_db.jobs.c.fence + 1, **values)).rowcount == 0:
        conn.execute(board_db.jobs.insert().values(submission_id=sub_id, fence=0, **values))
    conn.execute(submissions.update().where(submissions.c.id == sub_id).values(attempts=0))


def _archive(conn: Connection, sub_id: int, action: str, note: str, moved_at: str | None = None) -> int:
    """Take an entry off the board (its submission withdrawn, its rows kept), saying why; returns its row count."""
    audit_id = (conn.execute(sa.select(sa.func.max(local_entries.c.audit_id))).scalar() or 0) + 1
    moved_at = moved_at or _now()
    conn.execute(submissions.update().where(submissions.c.id == sub_id).values(withdrawn=_epoch(moved_at) or
                                                                               time.time(), updated=time.time()))
    # its job is cancelled: a run of it still going is refused at its next write
    conn.execute(board_db.jobs.update().where((board_db.jobs.c.submission_id == sub_id)
                                            & board_db.jobs.c.state.in_(("queued", "running"))).values(
        state="failed", lease_owner=None, lease_until=None, fence=board_db.jobs.c.fence + 1))
    conn.execute(local_entries.update().where(local_entries.c.submission_id == sub_id).values(
        action=action, note=note, moved_at=moved_at, audit_id=audit_id))
    return conn.execute(sa.select(sa.func.count()).select_from(board_db.rows)
                        .where(board_db.rows.c.submission_id == sub_id)).scalar()


def _import_tables(conn: Connection, tables: dict[str, list[dict[str, Any]]]) -> None:
    """Every entry, row and audit row of a schema-4 store onto the board (inside the caller's transaction)."""
    def entry(s: dict[str, Any], withdrawn: float | None = None) -> int:
        return _add_entry(conn, s["track"], s["track_hash"], s["name"], s["policy"], s["submitter"], s["status"],
                          s["reason"], {"builtin": bool(s["builtin"]), **{k: s[k] for k in _ENTRY_FIELDS[1:]},
                                        "wfbench_version": s["wfbench_version"], "created_at": s["created_at"]},
                          withdrawn)

    def rows(sub_id: int, found: list[dict[str, Any]]) -> None:
        for r in found:
            _add_row(conn, sub_id, r, int(r["seed"]), _epoch(r["finished_at"]), {c: r[c] for c in _PROVENANCE})

    results: dict[int, list[dict[str, Any]]] = {}
    for r in tables["results"]:
        results.setdefault(r["submission_id"], []).append(r)
    for s in tables["submissions"]:
        rows(entry(s), results.get(s["id"], []))
    audited: dict[int, list[dict[str, Any]]] = {}
    for r in tables["audit_results"]:
        audited.setdefault(r["audit_id"], []).append(r)
    for a in tables["audit_submissions"]:
        sub_id = entry(a, _epoch(a["moved_at"]) or time.time())
        rows(sub_id, audited.get(a["audit_id"], []))
        conn.execute(local_entries.update().where(local_entries.c.submission_id == sub_id).values(
            action=a["action"], note=a["note"], moved_at=a["moved_at"], audit_id=a["audit_id"]))


# -- showing -----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Shown:
    """What :func:`show` made: the text and the notes beside it."""

    text: str
    refused: list[str]  # stored rows the ranking could not use, one line each (warnings)
    left_out: list[str]  # complete entries the budget left unranked, one line each


def show(track: str | Track, db: Any = None, fmt: str = "table", baseline: str = "heuristic",
         max_decision_ms: float | None = None, max_cpu_s: float | None = None) -> Shown:
    """A track's board as ``wfbench leaderboard show`` prints it.

    Args:
        track: a track name or object.
        db: the board (a path, a :class:`Store`, a read-only
            :class:`~wfbench.leaderboard.schema4.Schema4Store`, or ``None`` for the default
            one); never created.
        fmt: ``table``, ``md``, ``csv`` or ``html`` (:data:`wfbench.leaderboard.report.FORMATS`).
        baseline: the entry the paired differences are taken to.
        max_decision_ms: rank only entries whose p99 wall time per decision is at most this.
        max_cpu_s: rank only entries that used at most this many CPU seconds per episode.

    Raises:
        ValueError: an unknown track or format.
        StoreError: no board at ``db``.
    """
    tr = get_track(track) if isinstance(track, str) else track
    report.check_format(fmt)
    store = db if isinstance(db, Store | Schema4Store) else Store(db, create=False)  # showing never creates one
    r = report.ranking(store, tr, baseline=baseline, max_decision_ms=max_decision_ms, max_cpu_s=max_cpu_s)
    return Shown(report.render(r, fmt), list(r.refused), list(r.left_out))
