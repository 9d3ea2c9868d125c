"""The local leaderboard: the hosted board's database (:class:`~wfbench.leaderboard.board.db.Board`) on a SQLite file.

An entry is a test-phase submission of the board (its policy spec the entry point, its
submitter the account, its seeds the track's published test seeds, ``seed_index`` the
seed itself); what only the local board records stands in the board's own columns
(revision ``0003``): a submission's fingerprint, budget, built-in mark and, for an entry
off the board, why it left; a row's provenance and digest. Replacing or withdrawing an
entry withdraws its submission: its rows stay, and :meth:`Store.audit` lists them. A
store of schema 4 (the sqlite3 file of earlier versions) is imported once when opened,
its file kept beside as ``NAME.schema4``. docs/leaderboard.md#one-board.
"""

from __future__ import annotations

import json
import math
import os
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
from wfbench.leaderboard.board.db import (
    PROVENANCE_COLUMNS,
    SHOWN,
    STATES,
    Board,
    Submission,
    accounts,
    kind_of_reason,
    packages,
    submissions,
    submissions_where,
)
from wfbench.leaderboard.board.migrations import NewerBoardError, check_known
from wfbench.leaderboard.rows import (
    BUDGET_ROW_COLUMNS,
    KPI_COLUMNS,
    ROW_COLUMNS,
    NameTaken,
    StoreError,
    budget_value,
    default_path,
    row_digest,
    scrub_paths,
)
from wfbench.leaderboard.schema4 import STATE, Schema4Store, is_schema4
from wfbench.leaderboard.tracks import Track, get_track

from wfbench.core.kpis import SCORE
from wfbench.harness.budget import BUDGET_COLUMNS

__all__ = ["KPI_COLUMNS", "ROW_COLUMNS", "BUDGET_ROW_COLUMNS", "NameTaken", "Store", "StoreError", "Shown",
           "default_path", "row_digest", "scrub_paths", "show"]

APPLICATION_ID = 0x57464232  # "WFB2": a local board (a schema-4 store is "WFB1")
PHASE = "test"  # a local entry runs the track's published test seeds
_ENTRY_FIELDS = ("builtin", "fingerprint", "fingerprint_detail", "budget", "wfbench_version", "created_at")
"""What a local entry records beyond the hosted columns (revision ``0003`` put them in ``submissions``)."""
_PROVENANCE = tuple(PROVENANCE_COLUMNS)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _epoch(text: str) -> float:
    try:
        return datetime.fromisoformat(text).timestamp()
    except (TypeError, ValueError):
        return 0.0


_ON_BOARD = submissions.c.withdrawn.is_(None)
_LOCAL = (submissions.c.phase == PHASE) & submissions.c.hidden_version.is_(None)


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
                             "'wfbench leaderboard submit' or 'baselines' wrote, or run one of them first")
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
        if app == APPLICATION_ID and "submissions" not in tables:
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
            board.create()  # a board made before revision 0003 has its local tables moved into the board's
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
    def submissions(self, track: str | None = None) -> list[Submission]:
        """The entries on the board (of ``track``), oldest first."""
        with self.engine.begin() as conn:
            return _on_board(conn, track)

    def find(self, track: str, name: str) -> Submission | None:
        with self.engine.begin() as conn:
            return _find(conn, track, name)

    def entries(self, track: str, phase: str = PHASE) -> list[Submission]:
        """The entries the ranking lists (:meth:`Board.entries <wfbench.leaderboard.board.db.Board.entries>`)."""
        return self.board.entries(track, phase)

    def results(self, track: Track, phase: str = PHASE) -> tuple[pd.DataFrame, list[str]]:
        """Valid rows of the track (with the entry's name) and one message per refused row (:meth:`Board.results`)."""
        return self.board.results(track, phase)

    def open_submission(self, track: Track, name: str, policy: str, submitter: str, version: str,
                        builtin: bool = False, fingerprint: str = "", fingerprint_detail: str = "",
                        replace: bool = False, budget: str = "") -> tuple[Submission, str]:
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
            existing = _find(conn, track.name, name)
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
                    conn.execute(submissions.update().where(submissions.c.id == existing.id).values(budget=budget))
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
            found = _find(conn, track, name)
            if found is None:
                there = [s.name for s in _on_board(conn, track)]
                raise StoreError(f"no entry {name!r} on track {track} in {self.path}; entries there: "
                                 f"{', '.join(there) if there else 'none'}")
            return _archive(conn, found.id, "withdrawn", note or "withdrawn")

        return self._write(f"the withdrawal of {name!r}", withdraw_)

    def audit(self, track: str | None = None) -> pd.DataFrame:
        """The audit trail: a row per result of an entry off the board (or per such entry without any), oldest first."""
        r = board_db.rows
        q = (sa.select(submissions.c.audit_id, submissions.c.track, submissions.c.name,
                       submissions.c.entry.label("policy"), submissions.c.fingerprint,
                       submissions.c.state.label("status"), submissions.c.audit_action.label("action"),
                       submissions.c.audit_note.label("note"), submissions.c.audit_at.label("moved_at"),
                       r.c.scenario, r.c.seed, r.c[SCORE], r.c.digest)
             .select_from(submissions.outerjoin(r, r.c.submission_id == submissions.c.id))
             .where(submissions.c.audit_id.is_not(None)).order_by(submissions.c.audit_id, r.c.scenario, r.c.seed))
        if track:
            q = q.where(submissions.c.track == track)
        with self.engine.begin() as conn:
            df = pd.read_sql_query(q, conn)
        return df.assign(status=df["status"].map(SHOWN))

    def set_status(self, sub_id: int, state: str, reason: str = "") -> None:
        """Set an entry's state (``running``, ``done`` or ``failed``, with the failure's one-line reason)."""
        if state not in STATES:
            raise StoreError(f"state {state!r} is not allowed; allowed: {', '.join(STATES)}")
        self._write("the submission status", lambda c: _set_state(c, sub_id, state, reason))

    def done_units(self, sub_id: int) -> set[tuple[str, int]]:
        """The (scenario, seed) pairs stored for an entry (scenario ``""`` on a one-scenario track)."""
        with self.engine.begin() as conn:
            return _done(conn, sub_id)

    def add_results(self, sub: Submission, version: str, rows: Iterable[dict[str, Any]]) -> int:
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

# -- writing, inside the caller's transaction ---------------------------------------------------------


def _find(conn: Connection, track: str, name: str) -> Submission | None:
    found = submissions_where(conn, (submissions.c.track == track) & (submissions.c.name == name) & _ON_BOARD
                              & _LOCAL)
    return found[0] if found else None


def _on_board(conn: Connection, track: str | None) -> list[Submission]:
    """The local entries on the board (of ``track``), oldest first."""
    return submissions_where(conn, _ON_BOARD & _LOCAL & (submissions.c.track == track if track else sa.true()))


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
        name=name, token_hash=board_db.token_hash(board_db.new_token()), admin=name == board_db.BUILTIN_ACCOUNT,
        created=time.time())).inserted_primary_key[0]


def _add_entry(conn: Connection, track: str, track_hash: str, name: str, policy: str, submitter: str, state: str,
               reason: str, entry: dict[str, Any], withdrawn: float | None = None) -> int:
    """Insert an entry: its submission (``entry``: its :data:`_ENTRY_FIELDS`) and its package (its own record)."""
    sub_id = (conn.execute(sa.select(sa.func.max(submissions.c.id))).scalar() or 0) + 1
    # a local entry has no package to run: its package is its record, one per entry (the board's key needs one)
    data = json.dumps({"local entry": sub_id, "track": track, "name": name, "policy": policy,
                       "fingerprint": entry["fingerprint"]}, sort_keys=True).encode()
    sha = board_db.package_sha(data)
    now = time.time()
    conn.execute(packages.insert().values(sha256=sha, bytes=data, size=len(data), created=now))
    failed = state == "failed"
    conn.execute(submissions.insert().values(
        id=sub_id, account_id=_account(conn, submitter), track=track, track_hash=track_hash, phase=PHASE,
        package_sha=sha, entry=policy, name=name, state=state, reason=reason,
        created=_epoch(entry["created_at"]) or now, updated=now, attempts=0, hidden_version=None, log="",
        result=None, fault="policy" if failed else "", kind=kind_of_reason(reason) if failed else "", spent_s=0.0,
        withdrawn=withdrawn, **entry))
    return sub_id


def _add_row(conn: Connection, sub_id: int, values: dict[str, Any], seed: int, finished: float,
             provenance: dict[str, Any] | None = None) -> None:
    scenario = values["scenario"]
    conn.execute(board_db.rows.insert().values(
        submission_id=sub_id, scenario=scenario, seed_index=seed, seed=seed, finished=finished,
        **{c: float(values[c]) for c in KPI_COLUMNS}, episode_length=int(values["episode_length"]),
        invalid_actions=int(values["invalid_actions"]), **{c: values.get(c) for c in BUDGET_ROW_COLUMNS},
        **(provenance or {})))


def add_provenance(conn: Connection, sub: Submission, version: str, rows: list[dict[str, Any]]) -> None:
    """Each new row's provenance and digest (the ``rows`` table's own columns), inside the caller's transaction.

    ``rows``: as just stored in the board's ``rows`` table (the seed is the seed index); the
    local worker's writes (:func:`wfbench.leaderboard.board.queue.write_rows`) call it.
    """
    r = board_db.rows
    for values in rows:
        seed = int(values["seed"])
        conn.execute(r.update().where((r.c.submission_id == sub.id) & (r.c.scenario == values["scenario"])
                                      & (r.c.seed_index == seed)).values(
            track=sub.track, track_hash=sub.track_hash, policy=sub.entry, submitter=sub.account,
            fingerprint=sub.fingerprint, wfbench_version=version, finished_at=_now(),
            digest=row_digest(sub.name, sub.track, sub.track_hash, sub.entry, sub.account, version, seed, values,
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
    audit_id = (conn.execute(sa.select(sa.func.max(submissions.c.audit_id))).scalar() or 0) + 1
    moved_at = moved_at or _now()
    conn.execute(submissions.update().where(submissions.c.id == sub_id).values(withdrawn=_epoch(moved_at) or
                                                                               time.time(), updated=time.time()))
    # its job is cancelled: a run of it still going is refused at its next write
    conn.execute(board_db.jobs.update().where((board_db.jobs.c.submission_id == sub_id)
                                            & board_db.jobs.c.state.in_(("queued", "running"))).values(
        state="failed", lease_owner=None, lease_until=None, fence=board_db.jobs.c.fence + 1))
    conn.execute(submissions.update().where(submissions.c.id == sub_id).values(
        audit_action=action, audit_note=note, audit_at=moved_at, audit_id=audit_id))
    return conn.execute(sa.select(sa.func.count()).select_from(board_db.rows)
                        .where(board_db.rows.c.submission_id == sub_id)).scalar()


def _import_tables(conn: Connection, tables: dict[str, list[dict[str, Any]]]) -> None:
    """Every entry, row and audit row of a schema-4 store onto the board (inside the caller's transaction)."""
    def entry(s: dict[str, Any], withdrawn: float | None = None) -> int:
        return _add_entry(conn, s["track"], s["track_hash"], s["name"], s["policy"], s["submitter"],
                          STATE[s["status"]], s["reason"],
                          {"builtin": bool(s["builtin"]), **{k: s[k] for k in _ENTRY_FIELDS[1:]}}, withdrawn)

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
        conn.execute(submissions.update().where(submissions.c.id == sub_id).values(
            audit_action=a["action"], audit_note=a["note"], audit_at=a["moved_at"], audit_id=a["audit_id"]))


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
    board = store.board if isinstance(store, Store) else store
    r = report.ranking(board, tr, baseline=baseline, max_decision_ms=max_decision_ms, max_cpu_s=max_cpu_s)
    return Shown(report.render(r, fmt), list(r.refused), list(r.left_out))
