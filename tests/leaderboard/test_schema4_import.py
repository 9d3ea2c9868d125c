"""A local store of schema 4 (wfbench's sqlite3 store before one board) is imported once, losing nothing."""

from __future__ import annotations

import json
import sqlite3

import pytest
from wfbench.leaderboard.rows import BUDGET_ROW_COLUMNS, ROW_COLUMNS, StoreError, row_digest
from wfbench.leaderboard.tracks import TRACKS

from tests.leaderboard.test_leaderboard import TINY
from wfbench.cli import main

# the schema-4 store as wfbench wrote it (leaderboard/store.py before issue #45), table by table
_SUB = """
    track TEXT NOT NULL, name TEXT NOT NULL, policy TEXT NOT NULL, submitter TEXT NOT NULL,
    track_hash TEXT NOT NULL, wfbench_version TEXT NOT NULL, created_at TEXT NOT NULL, {status},
    reason TEXT NOT NULL DEFAULT '', builtin INTEGER NOT NULL DEFAULT 0, fingerprint TEXT NOT NULL DEFAULT '',
    fingerprint_detail TEXT NOT NULL DEFAULT '', budget TEXT NOT NULL DEFAULT ''"""
_RES = """
    seed INTEGER NOT NULL, track TEXT NOT NULL, track_hash TEXT NOT NULL, policy TEXT NOT NULL,
    submitter TEXT NOT NULL, wfbench_version TEXT NOT NULL, finished_at TEXT NOT NULL,
    workforce_cost REAL NOT NULL, utilization REAL NOT NULL, downtime REAL NOT NULL, nsw REAL NOT NULL,
    episode_length INTEGER NOT NULL, invalid_actions INTEGER NOT NULL, digest TEXT NOT NULL,
    fingerprint TEXT NOT NULL DEFAULT '', decision_ms_p50 REAL, decision_ms_p99 REAL, cpu_s REAL, machine TEXT,
    scenario TEXT NOT NULL DEFAULT ''"""
SCHEMA_4 = f"""
CREATE TABLE submissions (id INTEGER PRIMARY KEY,{_SUB.format(
    status="status TEXT NOT NULL CHECK (status IN ('running', 'complete', 'failed'))")}, UNIQUE (track, name));
CREATE TABLE results (submission_id INTEGER NOT NULL REFERENCES submissions(id),{_RES},
    PRIMARY KEY (submission_id, scenario, seed));
CREATE TABLE audit_submissions (audit_id INTEGER PRIMARY KEY, submission_id INTEGER NOT NULL,{_SUB.format(
    status="status TEXT NOT NULL")}, action TEXT NOT NULL CHECK (action IN ('replaced', 'withdrawn')),
    note TEXT NOT NULL, moved_at TEXT NOT NULL);
CREATE TABLE audit_results (audit_id INTEGER NOT NULL REFERENCES audit_submissions(audit_id),
    submission_id INTEGER NOT NULL,{_RES}, PRIMARY KEY (audit_id, scenario, seed));
PRAGMA application_id = {0x57464231};
PRAGMA user_version = 4;
"""
SUB_COLUMNS = ("track", "name", "policy", "submitter", "track_hash", "wfbench_version", "created_at", "status",
               "reason", "builtin", "fingerprint", "fingerprint_detail", "budget")
RES_COLUMNS = ("seed", "track", "track_hash", "policy", "submitter", "wfbench_version", "finished_at", *ROW_COLUMNS,
               "digest", "fingerprint", *BUDGET_ROW_COLUMNS, "scenario")
BUDGET = json.dumps({"kind": "builtin"})
# name, policy, status, reason, builtin, fingerprint, budget, KPI offset, seeds, with a budget
ENTRIES = [
    ("heuristic", "heuristic", "complete", "", 1, "aaaa000011112222", BUDGET, 0.0, (0, 1, 2, 3), True),
    ("mine", "lbfp_mine:Mine", "complete", "", 0, "bbbb000011112222", "", 0.05, (0, 1, 2, 3), True),
    ("old", "random", "complete", "", 0, "", "", -0.1, (0, 1, 2, 3), False),  # legacy: stored before fingerprints
    ("broken", "lb_policies:Raises", "failed", "policy 'x' failed in act at lb_policies.py:25: boom", 0,
     "cccc000011112222", "", 0.02, (0,), True),
    ("half", "greedy", "running", "", 0, "dddd000011112222", "", 0.01, (0, 1), True),
]
# audit_id, submission_id, name, action, note, moved_at, KPI offset, seeds
AUDITED = [
    (1, 90, "gone", "withdrawn", "a wrong upload", "2026-01-02T03:04:05+00:00", 0.3, (0, 1)),
    (2, 91, "mine", "replaced", "replaced by --replace with fingerprint bbbb000011112222",
     "2026-01-03T03:04:05+00:00", 0.2, (0, 1, 2, 3)),
]


def _row(name, policy, fingerprint, offset, seed, budget, track_hash=None):
    values = {"workforce_cost": 100.0 + seed + offset, "utilization": 0.5 + offset / 2, "downtime": 0.1 * seed,
              "nsw": 0.4 + offset + 0.01 * seed, "episode_length": 60, "invalid_actions": seed % 2,
              "decision_ms_p50": 0.25 + seed if budget else None, "decision_ms_p99": 1.5 + seed if budget else None,
              "cpu_s": 0.75 if budget else None, "machine": "x86_64, 2 CPUs; serial, 1 worker" if budget else None,
              "scenario": ""}
    track_hash = track_hash or TINY.hash
    values["digest"] = row_digest(name, TINY.name, track_hash, policy, "me", "0.9", seed, values, fingerprint)
    return {"seed": seed, "track": TINY.name, "track_hash": track_hash, "policy": policy, "submitter": "me",
            "wfbench_version": "0.9", "finished_at": f"2026-01-01T00:00:0{seed}+00:00", "fingerprint": fingerprint,
            **values}


def _insert(conn, table, row):
    conn.execute(f"INSERT INTO {table} ({', '.join(row)}) VALUES ({', '.join('?' * len(row))})", tuple(row.values()))


def write_schema4(path):
    """A schema-4 store of TINY: ranked, legacy, failed and running entries, an edited row, audit rows."""
    conn = sqlite3.connect(path)
    conn.executescript(SCHEMA_4)
    for i, (name, policy, status, reason, builtin, fp, budget, offset, seeds, measured) in enumerate(ENTRIES, 1):
        detail = json.dumps({"kind": "builtin", "spec": policy}) if fp else ""
        sub = dict(zip(SUB_COLUMNS, (TINY.name, name, policy, "me", TINY.hash, "0.9", "2026-01-01T00:00:00+00:00",
                                     status, reason, builtin, fp, detail, budget), strict=True))
        _insert(conn, "submissions", {"id": i, **sub})
        for seed in seeds:
            _insert(conn, "results", {"submission_id": i, **_row(name, policy, fp, offset, seed, measured)})
    conn.execute("UPDATE results SET nsw = 0.99 WHERE submission_id = 2 AND seed = 3")  # edited: refused
    for audit_id, sub_id, name, action, note, moved, offset, seeds in AUDITED:
        sub = dict(zip(SUB_COLUMNS, (TINY.name, name, "greedy", "me", TINY.hash, "0.9", "2025-12-01T00:00:00+00:00",
                                     "complete", "", 0, "eeee000011112222", "{}", ""), strict=True))
        _insert(conn, "audit_submissions", {"audit_id": audit_id, "submission_id": sub_id, **sub, "action": action,
                                            "note": note, "moved_at": moved})
        for seed in seeds:
            _insert(conn, "audit_results", {"audit_id": audit_id, "submission_id": sub_id,
                                             **_row(name, "greedy", "eeee000011112222", offset, seed, True)})
    conn.commit()
    conn.close()


def _show(db, capsys, *extra):
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), *extra]) == 0
    return capsys.readouterr()


@pytest.fixture()
def tiny_on_cli(monkeypatch):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["table", "csv"])
def test_a_schema4_store_is_imported_once_and_shows_the_same_board(tmp_path, capsys, tiny_on_cli, fmt):
    from wfbench.leaderboard.schema4 import Schema4Store
    from wfbench.leaderboard.store import show

    db = tmp_path / "lb.sqlite"
    write_schema4(db)
    original = db.read_bytes()
    with Schema4Store(db) as old:  # the schema-4 file read as it is, nothing written
        before = show(TINY, old, fmt)
    assert db.read_bytes() == original
    first = _show(db, capsys, "--format", fmt)
    assert first.out.rstrip("\n") == before.text.rstrip("\n")
    assert first.err.splitlines() == [f"wfbench: warning: {m}" for m in before.refused]
    assert any("do not match its digest" in m for m in before.refused)
    backup = db.with_name(db.name + ".schema4")
    assert backup.read_bytes() == original, "the schema-4 file is kept as it was"
    second = _show(db, capsys, "--format", fmt)  # imported once: the board is read as it is now
    assert (second.out, second.err) == (first.out, first.err)
    assert backup.read_bytes() == original


def test_the_import_keeps_entries_rows_and_the_audit_trail(tmp_path):
    from wfbench.leaderboard.schema4 import Schema4Store
    from wfbench.leaderboard.store import Store

    db = tmp_path / "lb.sqlite"
    write_schema4(db)
    with Schema4Store(db) as old:
        old_subs, (old_rows, old_refused), old_audit = old.entries(), old.results(TINY), old.audit()
    store = Store(db)
    assert [(s.name, s.entry, s.status, s.reason, s.builtin, s.fingerprint, s.fingerprint_detail, s.budget,
             s.legacy) for s in store.submissions(TINY.name)] == \
        [(s.name, s.entry, s.status, s.reason, s.builtin, s.fingerprint, s.fingerprint_detail, s.budget, s.legacy)
         for s in old_subs]
    rows, refused = store.results(TINY)
    assert refused == old_refused
    same = ["name", "status", "seed", "track", "track_hash", "policy", "submitter", "wfbench_version", "finished_at",
            *ROW_COLUMNS, "digest", "fingerprint", *BUDGET_ROW_COLUMNS, "scenario"]
    assert rows[same].equals(old_rows[same])
    audit = store.audit(TINY.name)
    keep = ["track", "name", "policy", "fingerprint", "status", "action", "note", "moved_at", "scenario", "seed",
            "nsw", "digest"]
    assert audit[keep].equals(old_audit[keep])
    assert list(audit["action"].unique()) == ["withdrawn", "replaced"] and len(audit) == 6
    store.close()


def test_a_wal_store_is_imported_with_what_its_wal_holds(tmp_path):
    from wfbench.leaderboard.store import Store

    db = tmp_path / "lb.sqlite"
    write_schema4(db)
    with sqlite3.connect(db) as c:  # as wfbench wrote them: WAL, the last commit possibly still in the -wal file
        assert c.execute("PRAGMA journal_mode=WAL").fetchone()[0] == "wal"
    writer = sqlite3.connect(db)
    writer.execute("PRAGMA wal_autocheckpoint=0")
    writer.execute("UPDATE submissions SET reason = 'stopped' WHERE name = 'half'")
    writer.commit()
    assert db.with_name(db.name + "-wal").stat().st_size > 0
    # the writer still holds the file: refused in one line, nothing changed
    with pytest.raises(StoreError, match="cannot import store .*: database is locked; nothing was changed$"):
        Store(db)
    assert not db.with_name(db.name + ".schema4").exists()
    writer.close()
    store = Store(db)
    assert store.find(TINY.name, "half").reason == "stopped"
    assert store.imported_from == db.with_name(db.name + ".schema4")
    store.close()
