"""The result store: one SQLite file, one row per (submission, scenario, seed), every row with its provenance.

The scenario is ``""`` on a one-scenario track; a suite track (``suite-v1``) stores a row
per scenario id and seed.

Safety:

- Each finished chunk of seeds is written in its own transaction, WAL journal,
  ``synchronous=FULL``. Killing the writer at any moment (``kill -9`` included) loses
  at most the chunk being written and never corrupts the file. Submitting again
  resumes with the missing seeds.
- The file is marked as a wfbench store (``PRAGMA application_id``) and carries its
  schema version (``PRAGMA user_version``). Any other SQLite file, a file that is not
  SQLite, or a store from a newer wfbench is refused with a one-line message before
  anything is written.
- Every result row stores the track hash, the seed, the policy spec and its fingerprint
  (a digest of what the policy runs, ``wfbench.leaderboard.submit.policy_fingerprint``), the
  submitter, the wfbench version and the time, plus a digest over all of them and the KPIs. At
  read time a row is refused, with the reason, when its hash is not the track's
  current hash (another version of the track), its seed is not a test seed of the
  track, or its digest does not match (the row was edited).
- A name on a track belongs to one fingerprint. Rows never vanish: replacing an entry
  (``--replace``, or the first resubmission of a legacy entry) or withdrawing it moves
  its submission and rows, in the same transaction, to the audit tables
  (``audit_submissions``, ``audit_results``) with the action, a note and the time.
- Every result row also stores what it cost (schema 3): the milliseconds per decision
  (p50, p99), the CPU seconds of the episode and a line naming the machine it ran on
  (:mod:`wfbench.harness.budget`), covered by its digest; every submission stores what its
  policy states about its own cost (training env-steps, wall time and hardware, tuning
  trials, solver time limits) as JSON.
- An older store is upgraded in place when opened, in one transaction: schema 1 (before
  fingerprints) gets the fingerprint columns and the audit tables, schema 2 (before
  budgets) the budget columns, schema 3 (one row per seed) the ``scenario`` column in
  the results tables' primary key (SQLite changes a key only by rebuilding the table:
  the rows are copied to new tables). The new columns are empty for the old rows, which
  stay valid (their digest never covered a fingerprint, a budget or a scenario);
  schema-1 entries are marked legacy, and rows without a budget show none.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import sqlite3
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd
from wfbench.leaderboard.tracks import SuiteTrack, Track

from wfbench.core.kpis import KPI_NAMES, SCORE
from wfbench.harness.budget import BUDGET_COLUMNS

APPLICATION_ID = 0x57464231  # "WFB1"
# 1: no fingerprints, no audit tables; 2: no budgets; 3: one row per seed only (all upgraded in place when opened)
SCHEMA_VERSION = 4
# The KPI columns are the KPI table's names (wfbench.core.kpis), in its order, each a REAL: the SQL below is
# generated from them. A new KPI in the table changes the results tables, so it needs a new schema version whose
# migration adds its column to an existing store (and leaves it out of the digest of the rows stored before).
KPI_COLUMNS = KPI_NAMES
ROW_COLUMNS = (*KPI_COLUMNS, "episode_length", "invalid_actions")
# what a row cost (wfbench.harness.budget.BUDGET_COLUMNS, and the machine's line); NULL in rows stored before schema 3
BUDGET_ROW_COLUMNS = (*BUDGET_COLUMNS, "machine")

# each table's columns as schema 2 had them, then with what schema 3 added
_SUBMISSION_COLUMNS_2 = """
    track TEXT NOT NULL,
    name TEXT NOT NULL,
    policy TEXT NOT NULL,
    submitter TEXT NOT NULL,
    track_hash TEXT NOT NULL,
    wfbench_version TEXT NOT NULL,
    created_at TEXT NOT NULL,
    status TEXT NOT NULL,
    reason TEXT NOT NULL DEFAULT '',
    builtin INTEGER NOT NULL DEFAULT 0,
    fingerprint TEXT NOT NULL DEFAULT '',
    fingerprint_detail TEXT NOT NULL DEFAULT ''"""
_SUBMISSION_COLUMNS = _SUBMISSION_COLUMNS_2 + """,
    budget TEXT NOT NULL DEFAULT ''"""
_RESULT_COLUMNS_2 = """
    seed INTEGER NOT NULL,
    track TEXT NOT NULL,
    track_hash TEXT NOT NULL,
    policy TEXT NOT NULL,
    submitter TEXT NOT NULL,
    wfbench_version TEXT NOT NULL,
    finished_at TEXT NOT NULL,""" + "".join(f"""
    {kpi} REAL NOT NULL,""" for kpi in KPI_COLUMNS) + """
    episode_length INTEGER NOT NULL,
    invalid_actions INTEGER NOT NULL,
    digest TEXT NOT NULL,
    fingerprint TEXT NOT NULL DEFAULT ''"""
_RESULT_COLUMNS_3 = _RESULT_COLUMNS_2 + """,
    decision_ms_p50 REAL,
    decision_ms_p99 REAL,
    cpu_s REAL,
    machine TEXT"""
_RESULT_COLUMNS = _RESULT_COLUMNS_3 + """,
    scenario TEXT NOT NULL DEFAULT ''"""  # a suite track's scenario id; "" on a one-scenario track
# the columns add_results writes, in the order of its values
_INSERTED = ("submission_id", "seed", "track", "track_hash", "policy", "submitter", "wfbench_version", "finished_at",
             *ROW_COLUMNS, "digest", "fingerprint", *BUDGET_ROW_COLUMNS, "scenario")


def _names(columns: str) -> list[str]:
    """The column names of a column definition block."""
    return [line.split()[0] for line in columns.strip().strip(",").split(",\n")]


def _audit_schema(submission_columns: str, result_columns: str, key: str = "scenario, seed") -> str:
    """The audit tables: what replacing or withdrawing an entry took off the board, never deleted."""
    return f"""
CREATE TABLE audit_submissions (
    audit_id INTEGER PRIMARY KEY,
    submission_id INTEGER NOT NULL,{submission_columns},
    action TEXT NOT NULL CHECK (action IN ('replaced', 'withdrawn')),
    note TEXT NOT NULL,
    moved_at TEXT NOT NULL
);
CREATE TABLE audit_results (
    audit_id INTEGER NOT NULL REFERENCES audit_submissions(audit_id),
    submission_id INTEGER NOT NULL,{result_columns},
    PRIMARY KEY (audit_id, {key})
);
"""

_STATUS_CHECKED = "status TEXT NOT NULL CHECK (status IN ('running', 'complete', 'failed')),"
_SCHEMA = f"""
CREATE TABLE submissions (
    id INTEGER PRIMARY KEY,{_SUBMISSION_COLUMNS.replace("status TEXT NOT NULL,", _STATUS_CHECKED)},
    UNIQUE (track, name)
);
CREATE TABLE results (
    submission_id INTEGER NOT NULL REFERENCES submissions(id),{_RESULT_COLUMNS},
    PRIMARY KEY (submission_id, scenario, seed)
);
{_audit_schema(_SUBMISSION_COLUMNS, _RESULT_COLUMNS)}"""
# schema 1 -> 2 (the audit tables as schema 2 had them), then 2 -> 3, in one transaction
_MIGRATE_1_TO_2 = f"""
ALTER TABLE submissions ADD COLUMN fingerprint TEXT NOT NULL DEFAULT '';
ALTER TABLE submissions ADD COLUMN fingerprint_detail TEXT NOT NULL DEFAULT '';
ALTER TABLE results ADD COLUMN fingerprint TEXT NOT NULL DEFAULT '';
{_audit_schema(_SUBMISSION_COLUMNS_2, _RESULT_COLUMNS_2, "seed")}"""
_MIGRATE_2_TO_3 = "".join(
    [f"ALTER TABLE {table} ADD COLUMN budget TEXT NOT NULL DEFAULT '';" for table in ("submissions",
                                                                                     "audit_submissions")]
    + [f"ALTER TABLE {table} ADD COLUMN {column};" for table in ("results", "audit_results")
       for column in ("decision_ms_p50 REAL", "decision_ms_p99 REAL", "cpu_s REAL", "machine TEXT")])
# 3 -> 4: the results tables get a scenario column in their primary key, which SQLite can only do by rebuilding them
_MIGRATE_3_TO_4 = "".join(
    f"""CREATE TABLE {table}_4 ({parent}{_RESULT_COLUMNS}, PRIMARY KEY ({owner}, scenario, seed));
INSERT INTO {table}_4 ({', '.join([owner, *extra, *_names(_RESULT_COLUMNS_3)])})
    SELECT {', '.join([owner, *extra, *_names(_RESULT_COLUMNS_3)])} FROM {table};
DROP TABLE {table};
ALTER TABLE {table}_4 RENAME TO {table};
""" for table, parent, owner, extra in (
        ("results", "submission_id INTEGER NOT NULL REFERENCES submissions(id),", "submission_id", []),
        ("audit_results", "audit_id INTEGER NOT NULL REFERENCES audit_submissions(audit_id),\n"
                          "    submission_id INTEGER NOT NULL,", "audit_id", ["submission_id"])))


class StoreError(Exception):
    """A store that cannot be used as asked: printed as one line by the CLI."""


class NameTaken(StoreError):
    """The name is taken on the track by a policy with another fingerprint (or on another track version)."""

    def __init__(self, existing: Submission, why: str):
        super().__init__(why)
        self.existing = existing
        self.why = why  # "fingerprint" or "track"


def default_path() -> Path:
    """``$WFBENCH_DB``, else ``wfbench/results.sqlite`` in the user's data folder."""
    env = os.environ.get("WFBENCH_DB")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_data_dir("wfbench", appauthor=False)) / "results.sqlite"


_ABS_PATH = re.compile(r"(?<![\w.~])(?:/|[A-Za-z]:\\)(?:[^\s:'\"()<>,;]*[/\\])?([^\s:'\"()<>,;/\\]+)")


def scrub_paths(text: str, cwd: str | Path | None = None) -> str:
    """``text`` with absolute paths made relative to ``cwd`` when they are under it, else cut to the file name."""
    base = str(Path(cwd).resolve()) + os.sep if cwd is not None else None

    def sub(m: re.Match) -> str:
        path = m.group(0)
        if base and path.startswith(base):
            return path[len(base):]
        return m.group(1)

    return _ABS_PATH.sub(sub, text)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def row_digest(name: str, track: str, track_hash: str, policy: str, submitter: str, version: str, seed: int,
               values: dict[str, Any], fingerprint: str = "") -> str:
    """sha256 over a row's provenance, values and budget.

    A legacy row (no fingerprint) keeps its schema-1 digest, a row without a budget
    (no ``machine``: stored before schema 3) its schema-2 digest, and a row of a
    one-scenario track (``scenario`` empty) the digest it had before schema 4.
    """
    payload = [name, track, track_hash, policy, submitter, version, int(seed)]
    payload += [float(values[c]).hex() if c in KPI_COLUMNS else int(values[c]) for c in ROW_COLUMNS]
    if fingerprint:
        payload.append(fingerprint)
    if values.get("machine"):
        payload += [_budget_value(values.get(c)) for c in BUDGET_COLUMNS] + [values["machine"]]
    if values.get("scenario"):
        payload += ["scenario", values["scenario"]]
    return hashlib.sha256(json.dumps(payload).encode()).hexdigest()


def _budget_value(v: Any) -> str | None:
    """A budget measurement as stored: its exact float, or None for a missing one (SQLite keeps no NaN)."""
    if v is None or not math.isfinite(float(v)):
        return None
    return float(v).hex()


@dataclass(frozen=True)
class Submission:
    id: int
    track: str
    name: str
    policy: str
    submitter: str
    track_hash: str
    status: str
    reason: str
    builtin: bool
    fingerprint: str = ""  # "" for a legacy entry, stored before fingerprints (schema 1)
    fingerprint_detail: str = ""  # JSON: what the fingerprint covers
    # JSON: what the policy states about its cost (wfbench.harness.budget.policy_budget); "" before schema 3
    budget: str = ""

    @property
    def legacy(self) -> bool:
        return not self.fingerprint


class Store:
    """A wfbench result store at ``path``.

    Args:
        path: the store file (default: :func:`default_path`).
        create: make the store when the file does not exist (writers do); readers pass
            ``False`` and get a StoreError saying the file does not exist.
    """

    def __init__(self, path: str | os.PathLike | None = None, create: bool = True):
        self.path = Path(path) if path is not None else default_path()
        exists = self.path.exists()
        if exists:
            self._check_file()
        elif not create:
            raise StoreError(f"store {self.path} does not exist; pass --db with the file that "
                             "'wfbench leaderboard submit' or 'seed' wrote, or run one of them first")
        else:
            if self.path.parent.exists() and not self.path.parent.is_dir():
                raise StoreError(f"cannot create store {self.path}: {self.path.parent} is not a folder")
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise StoreError(f"cannot create store {self.path}: {exc.strerror or exc}") from None
        try:
            self.conn = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        except sqlite3.Error as exc:
            raise StoreError(f"cannot open store {self.path}: {exc}") from None
        self.conn.row_factory = sqlite3.Row
        try:
            self.conn.execute("PRAGMA journal_mode=WAL")
            self.conn.execute("PRAGMA synchronous=FULL")
            self.conn.execute("PRAGMA foreign_keys=ON")
            if exists:
                self._check_schema()
            else:
                self._create()
        except sqlite3.DatabaseError as exc:
            self.conn.close()
            raise StoreError(f"{self.path} is not a usable wfbench store: {exc}") from None

    # -- opening -----------------------------------------------------------------------------------
    def _check_file(self) -> None:
        if self.path.is_dir():
            raise StoreError(f"{self.path} is a folder, not a wfbench store file")
        try:
            with open(self.path, "rb") as fh:
                head = fh.read(16)
        except OSError as exc:
            raise StoreError(f"cannot read store {self.path}: {exc.strerror or exc}") from None
        if head and head != b"SQLite format 3\x00":
            raise StoreError(f"{self.path} is not a wfbench store (not an SQLite database); "
                             "pass --db with another path")

    def _check_schema(self) -> None:
        app = self.conn.execute("PRAGMA application_id").fetchone()[0]
        version = self.conn.execute("PRAGMA user_version").fetchone()[0]
        tables = {r[0] for r in self.conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if app == 0 and version == 0 and not tables:  # an empty file: make it a store
            self._create()
            return
        if app != APPLICATION_ID:
            raise StoreError(f"{self.path} is an SQLite database but not a wfbench store; pass --db with another path")
        if version > SCHEMA_VERSION:
            raise StoreError(f"{self.path} was written by a newer wfbench (store schema {version}; this wfbench "
                             f"reads up to {SCHEMA_VERSION}): upgrade wfbench to read it")
        if not {"submissions", "results"} <= tables:
            raise StoreError(f"{self.path} is marked as a wfbench store but its tables are missing")
        if version < SCHEMA_VERSION:
            self._migrate()

    def _migrate(self) -> None:
        """Upgrade a schema-1 or -2 store in place, in one transaction (another process may be doing the same)."""
        self.conn.execute("BEGIN IMMEDIATE")
        try:
            version = self.conn.execute("PRAGMA user_version").fetchone()[0]
            if version in (1, 2, 3):
                steps = [_MIGRATE_1_TO_2, _MIGRATE_2_TO_3, _MIGRATE_3_TO_4][version - 1:]
                for stmt in ";".join(steps).split(";"):
                    if stmt.strip():
                        self.conn.execute(stmt)
                self.conn.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            elif version != SCHEMA_VERSION:
                raise StoreError(f"{self.path} has store schema {version}, which this wfbench cannot upgrade")
            self.conn.execute("COMMIT")
        except sqlite3.OperationalError as exc:
            if self.conn.in_transaction:
                self.conn.execute("ROLLBACK")
            raise StoreError(f"cannot upgrade store {self.path} to schema {SCHEMA_VERSION}: {exc}; nothing was "
                             "changed (is the file read-only?)") from None
        except BaseException:
            if self.conn.in_transaction:
                self.conn.execute("ROLLBACK")
            raise

    def _create(self) -> None:
        # one explicit transaction (executescript would commit on its own)
        self.conn.execute("BEGIN IMMEDIATE")
        try:
            for stmt in _SCHEMA.split(";"):
                if stmt.strip():
                    self.conn.execute(stmt)
            self.conn.execute(f"PRAGMA application_id={APPLICATION_ID}")
            self.conn.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            self.conn.execute("COMMIT")
        except BaseException:
            self.conn.execute("ROLLBACK")
            raise

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- transactions ------------------------------------------------------------------------------
    class _Tx:
        def __init__(self, store: Store):
            self.store = store

        def __enter__(self) -> sqlite3.Connection:
            self.store.conn.execute("BEGIN IMMEDIATE")
            return self.store.conn

        def __exit__(self, exc_type, exc, tb) -> None:
            conn = self.store.conn
            if exc_type is None:
                try:
                    conn.execute("COMMIT")
                    return
                except sqlite3.Error:
                    if conn.in_transaction:
                        conn.execute("ROLLBACK")
                    raise
            if conn.in_transaction:  # SQLite rolls back by itself on some errors (a full disk)
                conn.execute("ROLLBACK")

    def _tx(self) -> Store._Tx:
        return Store._Tx(self)

    def _write(self, what: str, fn) -> Any:
        try:
            with self._tx() as conn:
                return fn(conn)
        except sqlite3.OperationalError as exc:
            text = str(exc)
            if "full" in text:
                raise StoreError(f"cannot write {what} to {self.path}: the disk is full ({text}); nothing was lost, "
                                 "finished seeds are kept: free space and submit again to resume") from None
            raise StoreError(f"cannot write {what} to {self.path}: {text}") from None

    # -- submissions -------------------------------------------------------------------------------
    def submissions(self, track: str | None = None) -> list[Submission]:
        q = "SELECT * FROM submissions" + (" WHERE track = ?" if track else "") + " ORDER BY id"
        return [self._sub(r) for r in self.conn.execute(q, (track,) if track else ())]

    @staticmethod
    def _sub(r: sqlite3.Row) -> Submission:
        return Submission(r["id"], r["track"], r["name"], r["policy"], r["submitter"], r["track_hash"], r["status"],
                          r["reason"], bool(r["builtin"]), r["fingerprint"], r["fingerprint_detail"], r["budget"])

    def find(self, track: str, name: str) -> Submission | None:
        r = self.conn.execute("SELECT * FROM submissions WHERE track = ? AND name = ?", (track, name)).fetchone()
        return self._sub(r) if r else None

    def open_submission(self, track: Track | SuiteTrack, name: str, policy: str, submitter: str, version: str,
                        builtin: bool = False, fingerprint: str = "", fingerprint_detail: str = "",
                        replace: bool = False, budget: str = "") -> tuple[Submission, str]:
        """The entry ``name`` of ``track`` for a policy with this fingerprint, in one transaction.

        Returns the submission and what happened: ``"new"``, ``"resumed"`` (same
        fingerprint and track version: only missing seeds are to be evaluated),
        ``"replaced"`` (``replace``: the old entry went to the audit tables) or
        ``"legacy"`` (the old entry had no fingerprint: it went to the audit tables, and
        every seed is evaluated anew). ``budget`` (JSON) is what the policy states about
        its cost; a resumed entry takes it too (an entry stored before schema 3 had none).

        Raises:
            NameTaken: the name is taken by another fingerprint or was made on another
                version of the track, and ``replace`` is not set.
        """
        if not name or len(name) > 100 or any(c in name for c in "\n\r\t"):
            raise StoreError(f"submission name {name!r} is not allowed; allowed: 1-100 characters, one line")

        def open_(conn: sqlite3.Connection) -> str:
            r = conn.execute("SELECT * FROM submissions WHERE track = ? AND name = ?", (track.name, name)).fetchone()
            existing = self._sub(r) if r else None
            action = "new"
            if existing is not None:
                if replace:
                    self._archive(conn, existing, "replaced", f"replaced by --replace with fingerprint {fingerprint}")
                    action = "replaced"
                elif existing.legacy:
                    self._archive(conn, existing, "replaced", "stored without a fingerprint (store schema 1); "
                                  f"re-evaluated on resubmission with fingerprint {fingerprint}")
                    action = "legacy"
                elif existing.fingerprint != fingerprint:
                    raise NameTaken(existing, "fingerprint")
                elif existing.track_hash != track.hash:
                    raise NameTaken(existing, "track")
                else:
                    conn.execute("UPDATE submissions SET status = 'running', reason = '', budget = ? WHERE id = ?",
                                 (budget, existing.id))
                    return "resumed"
            conn.execute(
                "INSERT INTO submissions (track, name, policy, submitter, track_hash, wfbench_version, created_at, "
                "status, builtin, fingerprint, fingerprint_detail, budget) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, 'running', ?, ?, ?, ?)",
                (track.name, name, policy, submitter, track.hash, version, _now(), int(builtin), fingerprint,
                 fingerprint_detail, budget),
            )
            return action

        action = self._write(f"submission {name!r}", open_)
        return self.find(track.name, name), action  # type: ignore[return-value]

    def _archive(self, conn: sqlite3.Connection, sub: Submission, action: str, note: str) -> int:
        """Move ``sub`` and its rows to the audit tables and off the board (inside the caller's transaction)."""
        cols = [r[1] for r in conn.execute("PRAGMA table_info(submissions)") if r[1] != "id"]
        cur = conn.execute(
            f"INSERT INTO audit_submissions (submission_id, {', '.join(cols)}, action, note, moved_at) "
            f"SELECT id, {', '.join(cols)}, ?, ?, ? FROM submissions WHERE id = ?", (action, note, _now(), sub.id))
        audit_id = cur.lastrowid
        rcols = [r[1] for r in conn.execute("PRAGMA table_info(results)")]
        n = conn.execute(f"INSERT INTO audit_results (audit_id, {', '.join(rcols)}) "
                         f"SELECT ?, {', '.join(rcols)} FROM results WHERE submission_id = ?",
                         (audit_id, sub.id)).rowcount
        conn.execute("DELETE FROM results WHERE submission_id = ?", (sub.id,))
        conn.execute("DELETE FROM submissions WHERE id = ?", (sub.id,))
        return n

    def withdraw(self, track: str, name: str, note: str = "") -> int:
        """Take the entry ``name`` off ``track``'s board: its rows go to the audit tables; returns how many.

        Raises:
            StoreError: no entry of that name on the track (the message names those there are).
        """
        def withdraw_(conn: sqlite3.Connection) -> int:
            r = conn.execute("SELECT * FROM submissions WHERE track = ? AND name = ?", (track, name)).fetchone()
            if r is None:
                there = [x[0] for x in conn.execute("SELECT name FROM submissions WHERE track = ? ORDER BY id",
                                                     (track,))]
                raise StoreError(f"no entry {name!r} on track {track} in {self.path}; entries there: "
                                 f"{', '.join(there) if there else 'none'}")
            return self._archive(conn, self._sub(r), "withdrawn", note or "withdrawn")

        return self._write(f"the withdrawal of {name!r}", withdraw_)

    def audit(self, track: str | None = None) -> pd.DataFrame:
        """The audit trail: one row per archived result (or per archived entry that had none), oldest first."""
        q = ("SELECT a.audit_id, a.track, a.name, a.policy, a.fingerprint, a.status, a.action, a.note, a.moved_at, "
             f"r.scenario, r.seed, r.{SCORE}, r.digest FROM audit_submissions a "
             "LEFT JOIN audit_results r ON r.audit_id = a.audit_id"
             + (" WHERE a.track = ?" if track else "") + " ORDER BY a.audit_id, r.scenario, r.seed")
        return pd.read_sql_query(q, self.conn, params=(track,) if track else ())

    def set_status(self, sub_id: int, status: str, reason: str = "") -> None:
        self._write("the submission status", lambda c: c.execute(
            "UPDATE submissions SET status = ?, reason = ? WHERE id = ?", (status, reason, sub_id)))

    def done_seeds(self, sub_id: int) -> set[int]:
        return {r[0] for r in self.conn.execute("SELECT seed FROM results WHERE submission_id = ?", (sub_id,))}

    def done_units(self, sub_id: int) -> set[tuple[str, int]]:
        """The (scenario, seed) pairs stored for a submission (scenario ``""`` on a one-scenario track)."""
        return {(r[0], r[1]) for r in self.conn.execute("SELECT scenario, seed FROM results WHERE submission_id = ?",
                                                         (sub_id,))}

    def add_results(self, sub: Submission, version: str, rows: Iterable[dict[str, Any]]) -> int:
        """Store finished seeds in one transaction; returns how many were new.

        A row holds the KPIs, ``episode_length`` and ``invalid_actions``, and its budget
        (:data:`BUDGET_ROW_COLUMNS`) when measured: a missing or non-finite measurement is
        stored as NULL. On a suite track each row names its ``scenario``.
        """
        rows = list(rows)
        for row in rows:
            bad = [c for c in KPI_COLUMNS if not math.isfinite(float(row[c]))]
            if bad:
                raise StoreError(f"seed {row['seed']}: non-finite {', '.join(bad)}; the row was not stored")

        def insert(conn: sqlite3.Connection) -> int:
            n = 0
            for row in rows:
                seed = int(row["seed"])
                budget = {c: None if _budget_value(row.get(c)) is None else float(row[c]) for c in BUDGET_COLUMNS}
                budget["machine"] = row.get("machine") or None
                scenario = str(row.get("scenario") or "")
                values = {**row, **budget, "scenario": scenario}
                digest = row_digest(sub.name, sub.track, sub.track_hash, sub.policy, sub.submitter, version, seed,
                                    values, sub.fingerprint)
                cur = conn.execute(
                    f"INSERT OR IGNORE INTO results ({', '.join(_INSERTED)}) "
                    f"VALUES ({', '.join('?' * len(_INSERTED))})",
                    (sub.id, seed, sub.track, sub.track_hash, sub.policy, sub.submitter, version, _now(),
                     *(float(row[c]) for c in KPI_COLUMNS), int(row["episode_length"]),
                     int(row["invalid_actions"]), digest, sub.fingerprint, *budget.values(), scenario),
                )
                n += cur.rowcount
            return n

        return self._write(f"{len(rows)} result(s) of {sub.name!r}", insert)

    # -- reading -----------------------------------------------------------------------------------
    def results(self, track: Track | SuiteTrack) -> tuple[pd.DataFrame, list[str]]:
        """Valid rows of the track (with the submission name) and one message per refused row."""
        q = ("SELECT s.name, s.status, s.builtin, r.* FROM results r JOIN submissions s ON s.id = r.submission_id "
             "WHERE r.track = ? ORDER BY s.id, r.scenario, r.seed")
        keep, refused = [], []
        test = set(track.test_seeds)
        units = set(track.units())
        for r in self.conn.execute(q, (track.name,)):
            d = dict(r)
            where = f"result of {d['name']!r}, {'scenario ' + d['scenario'] + ', ' if d['scenario'] else ''}" \
                    f"seed {d['seed']}"
            if d["track_hash"] != track.hash:
                refused.append(f"{where}: made on another version of track {track.name} (hash {d['track_hash']}, "
                               f"current {track.hash}); refused")
                continue
            if d["seed"] not in test:
                refused.append(f"{where}: seed {d['seed']} is not a test seed of track {track.name}; refused")
                continue
            if (d["scenario"], d["seed"]) not in units:
                refused.append(f"{where}: scenario {d['scenario'] or '(none)'!r} is not one of track {track.name}'s; "
                               "refused")
                continue
            expected = row_digest(d["name"], d["track"], d["track_hash"], d["policy"], d["submitter"],
                                  d["wfbench_version"], d["seed"], d, d["fingerprint"])
            if expected != d["digest"]:
                refused.append(f"{where}: its values do not match its digest (the row was edited); refused")
                continue
            keep.append(d)
        df = pd.DataFrame(keep, columns=["name", "status", "builtin", "submission_id", "seed", "track", "track_hash",
                                         "policy", "submitter", "wfbench_version", "finished_at", *ROW_COLUMNS,
                                         "digest", "fingerprint", *BUDGET_ROW_COLUMNS, "scenario"])
        return df, refused
