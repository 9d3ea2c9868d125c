"""Reading a local store of schema 4, the sqlite3 file wfbench wrote before the local board was the hosted one.

:class:`Schema4Store` reads such a file as it is (never writing to it): its entries (as the
board's :class:`~wfbench.leaderboard.board.db.Submission` records), its valid rows with the
refused ones' messages, and its audit trail; the reports rank it as a board. The local board
(:mod:`wfbench.leaderboard.store`) imports it once from these; docs/leaderboard.md#one-board.
Stores of schemas 1 to 3 are upgraded to 4 by an earlier wfbench (before issue #45) first.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import pandas as pd
from wfbench.leaderboard.board.db import Submission
from wfbench.leaderboard.rows import RESULT_FRAME_COLUMNS, StoreError, check_rows

from wfbench.core.kpis import SCORE

APPLICATION_ID = 0x57464231  # "WFB1": the mark of a schema-1 to -4 store
SCHEMA_VERSION = 4
ENTRY_FIELDS = ("track", "name", "policy", "submitter", "track_hash", "wfbench_version", "created_at", "status",
                "reason", "builtin", "fingerprint", "fingerprint_detail", "budget")
"""A schema-4 entry's columns after its id (``submissions``; ``audit_submissions`` after its audit and entry ids)."""
STATE = {"running": "running", "complete": "done", "failed": "failed"}
"""A schema-4 entry's status word as the board's state (the board shows it as it was: ``SHOWN``)."""


def is_schema4(conn: sqlite3.Connection, path: Path) -> bool:
    """True for a schema-4 store; False for a file without the mark; StoreError for another schema of it."""
    if conn.execute("PRAGMA application_id").fetchone()[0] != APPLICATION_ID:
        return False
    version = conn.execute("PRAGMA user_version").fetchone()[0]
    if version > SCHEMA_VERSION:
        raise StoreError(f"{path} was written by a newer wfbench (store schema {version}; this wfbench imports "
                         f"schema {SCHEMA_VERSION}): upgrade wfbench to read it")
    if version < SCHEMA_VERSION:
        raise StoreError(f"{path} is a store of schema {version}, which this wfbench does not import (it imports "
                         f"schema {SCHEMA_VERSION}); open it once with an earlier wfbench (before issue #45) to "
                         "upgrade it to schema 4 first")
    return True


def submission(r: dict[str, Any]) -> Submission:
    """A schema-4 ``submissions`` row as the board's record of a local entry (the test phase on published seeds)."""
    return Submission(r["id"], 0, r["submitter"], r["track"], r["track_hash"], "test", "", r["policy"], r["name"],
                      STATE[r["status"]], r["reason"], 0.0, 0.0, 0, None, "", None, builtin=bool(r["builtin"]),
                      fingerprint=r["fingerprint"], fingerprint_detail=r["fingerprint_detail"], budget=r["budget"])


class Schema4Store:
    """A schema-4 store file, read only: what it holds, as that wfbench showed it."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.conn = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True)
        self.conn.row_factory = sqlite3.Row
        try:
            if not is_schema4(self.conn, self.path):
                raise StoreError(f"{self.path} is not a wfbench store of schema {SCHEMA_VERSION}")
        except BaseException:
            self.conn.close()
            raise

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> Schema4Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def table(self, name: str, order: str) -> list[dict[str, Any]]:
        """Every row of a table, as dicts, in ``order``."""
        return [dict(r) for r in self.conn.execute(f"SELECT * FROM {name} ORDER BY {order}")]

    def entries(self, track: str | None = None, phase: str = "test") -> list[Submission]:
        """Its entries (of ``track``), oldest first; ``phase``: a local store's are all of the test phase."""
        return [submission(r) for r in self.table("submissions", "id") if track in (None, r["track"])
                and phase == "test"]

    def results(self, track: Any, phase: str = "test") -> tuple[pd.DataFrame, list[str]]:
        """Valid rows of the track (with the entry's name) and one message per refused row."""
        q = ("SELECT s.name, s.status, s.builtin, r.* FROM results r JOIN submissions s ON s.id = r.submission_id "
             "WHERE r.track = ? ORDER BY s.id, r.scenario, r.seed")
        keep, refused = check_rows([dict(r) for r in self.conn.execute(q, (track.name,))], track)
        return pd.DataFrame(keep, columns=list(RESULT_FRAME_COLUMNS)), refused

    def audit(self, track: str | None = None) -> pd.DataFrame:
        """The audit trail: one row per archived result (or per archived entry that had none), oldest first."""
        q = ("SELECT a.audit_id, a.track, a.name, a.policy, a.fingerprint, a.status, a.action, a.note, a.moved_at, "
             f"r.scenario, r.seed, r.{SCORE}, r.digest FROM audit_submissions a "
             "LEFT JOIN audit_results r ON r.audit_id = a.audit_id"
             + (" WHERE a.track = ?" if track else "") + " ORDER BY a.audit_id, r.scenario, r.seed")
        return pd.read_sql_query(q, self.conn, params=(track,) if track else ())
