"""The hosted board's Alembic migrations, on SQLite and PostgreSQL: an empty database to head, a board made before
Alembic upgraded in place with its rows, and the head schema equal to the SQLAlchemy metadata.

The two ``tests/data/hosted_board/pre_alembic.*.sql`` files are dumps (``sqlite3 .dump``, ``pg_dump --inserts``)
of boards made by the code before Alembic (commit 4417306): three accounts, a done, a failed, a withdrawn, a test-
phase and a queued submission, their rows, and an ended test phase.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from wfbench.leaderboard.board import migrations
from wfbench.leaderboard.board.db import Board, metadata

from tests.leaderboard.test_hosted_db import TINY, run_fake

DUMPS = Path(__file__).parents[1] / "data" / "hosted_board"
HEAD = ScriptDirectory.from_config(migrations.config()).get_current_head()


def load_dump(url: str) -> None:
    """Make the database at ``url`` what the code before Alembic left (its own dump, run as it is)."""
    if "://" not in url:
        with sqlite3.connect(url) as conn:
            conn.executescript((DUMPS / "pre_alembic.sqlite.sql").read_text())
        return
    engine = sa.create_engine(url)
    try:
        raw = engine.raw_connection()
        raw.driver_connection.execute((DUMPS / "pre_alembic.postgresql.sql").read_text())
        raw.commit()
        raw.close()
    finally:
        engine.dispose()


def contents(engine) -> dict[str, list[tuple]]:
    """Every table's rows (alembic_version aside), sorted, as tuples of their columns by name."""
    out = {}
    with engine.connect() as conn:
        for name in sorted(sa.inspect(conn).get_table_names()):
            if name != "alembic_version":
                table = sa.Table(name, sa.MetaData(), autoload_with=conn)
                out[name] = sorted((tuple(sorted(r.items())) for r in conn.execute(table.select()).mappings()),
                                   key=repr)
    return out


def schema(engine) -> dict[str, dict]:
    """What the database says of each table: columns, keys, constraints and indexes, by name where they have one."""
    with engine.connect() as conn:
        seen = sa.inspect(conn)
        return {t: {"columns": [(c["name"], str(c["type"]), c["nullable"]) for c in seen.get_columns(t)],
                    "primary": seen.get_pk_constraint(t)["constrained_columns"],
                    "foreign": sorted((f["constrained_columns"], f["referred_table"])
                                      for f in seen.get_foreign_keys(t)),
                    "unique": sorted((u["name"], u["column_names"]) for u in seen.get_unique_constraints(t)),
                    "check": sorted(c["name"] for c in seen.get_check_constraints(t)),
                    "indexes": sorted((i["name"], i["column_names"]) for i in seen.get_indexes(t)
                                      if not i.get("duplicates_constraint"))}
                for t in seen.get_table_names()}


def old_columns(now: dict[str, list[tuple]], before: dict[str, list[tuple]]) -> dict[str, list[tuple]]:
    """``now``'s rows cut to the columns each table had ``before`` (a revision since added columns)."""
    out = {}
    for name, rows in now.items():
        kept = {c for row in before.get(name, []) for c, _ in row}
        out[name] = sorted((tuple((c, v) for c, v in row if c in kept) for row in rows), key=repr) if kept else rows
    return out


# what revision 0003 added (issue #54: the local board's columns), and what a hosted board holds in them
LOCAL_DEFAULTS = {"submissions": {"builtin": False, "fingerprint": "", "fingerprint_detail": "", "budget": "",
                                  "wfbench_version": "", "created_at": "", "audit_action": "", "audit_note": "",
                                  "audit_at": "", "audit_id": None},
                  "rows": dict.fromkeys(("track", "track_hash", "policy", "submitter", "fingerprint",
                                         "wfbench_version", "finished_at", "digest"))}


def differences(engine) -> list:
    with engine.connect() as conn:
        return compare_metadata(MigrationContext.configure(conn), metadata)


def test_an_empty_database_is_upgraded_to_head_and_matches_the_metadata(db_url):
    board = Board(db_url, tracks={"tiny": TINY})
    board.create()
    board.create()  # on every start: nothing more to do
    with board.engine.connect() as conn:
        assert migrations.current(conn) == HEAD == "0003"
    assert set(sa.inspect(board.engine).get_table_names()) == {*metadata.tables, "alembic_version"}
    assert differences(board.engine) == []
    alice = board.account(board.add_account("alice"))
    sub, created = board.submit(alice, "tiny", "dev", board.put_package(b"p"), "p:P", "p")
    run_fake(board, sub, 0.5)
    assert created and board.submission(sub.id).state == "done" and len(board.rows(sub.id)) == 3
    board.close()


def test_a_board_made_before_alembic_is_upgraded_in_place_with_every_row(db_url, tmp_path):
    load_dump(db_url)
    board = Board(db_url, tracks={"tiny": TINY})
    with board.engine.connect() as conn:
        assert migrations.pre_alembic_revision(conn) == "0002" and migrations.current(conn) is None
    before = contents(board.engine)
    board.create()
    with board.engine.connect() as conn:
        assert migrations.current(conn) == HEAD
    after = contents(board.engine)
    assert old_columns(after, before) == before and len(before["rows"]) == 59
    for table, defaults in LOCAL_DEFAULTS.items():  # the local board's columns, empty on a hosted board
        assert all({c: v for c, v in row if c in defaults} == defaults for row in after[table]), table
    assert [(s.id, s.state, s.withdrawn is not None) for s in board.submissions()] == [
        (1, "done", False), (2, "failed", False), (3, "done", False), (4, "withdrawn", True), (5, "queued", False)]
    assert (board.submission(2).fault, board.submission(2).kind) == ("policy", "timed out")
    assert board.test_phase_ended("tiny") is not None
    alice = board.account_by_name("alice")
    assert alice is not None and board.submit(alice, "tiny", "dev", board.submission(1).package_sha, "pa:Policy",
                                              "again")[0].id == 1, "the old dedupe still finds alice's entry"
    assert differences(board.engine) == []
    fresh = Board(tmp_path / "fresh.sqlite", tracks={"tiny": TINY}) if "://" not in db_url else None
    if fresh is not None:  # on SQLite the rebuilt tables must also read back as a fresh board's do
        fresh.create()
        assert schema(board.engine) == schema(fresh.engine)
        fresh.close()
    board.close()


def test_the_first_revision_upgrades_to_head_with_its_rows(db_url):
    board = Board(db_url, tracks={"tiny": TINY})
    migrations.upgrade(board.engine, "0001")
    with board.engine.connect() as conn:
        assert migrations.current(conn) == "0001" and migrations.pre_alembic_revision(conn) is None
    with board.engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO accounts (name, token_hash, admin, created) VALUES ('a', 'h', false, 1)")
        conn.exec_driver_sql("INSERT INTO packages VALUES ('sha256:x', 'x', 1, 1)")
        conn.exec_driver_sql("INSERT INTO submissions (account_id, track, track_hash, phase, package_sha, entry, name, "
                             "state, reason, created, updated, attempts, log) VALUES (1, 'tiny', 'h', 'dev', "
                             "'sha256:x', 'p:P', 'p', 'failed', 'out of memory (the memory limit)', 1, 1, 1, '')")
    board.create()
    sub = board.submission(1)
    assert (sub.name, sub.state, sub.fault, sub.kind, sub.spent_s) == ("p", "failed", "policy", "out of memory", 0.0)
    assert differences(board.engine) == []
    board.close()


def test_a_server_and_workers_starting_together_migrate_once(db_url):
    """Each start calls Board.create(); four at once on an empty database all end at head, with one key secret."""
    boards = [Board(db_url, tracks={"tiny": TINY}) for _ in range(4)]
    errors = []

    def start(board):
        try:
            board.create()
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(exc)

    threads = [threading.Thread(target=start, args=(b,)) for b in boards]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    with boards[0].engine.connect() as conn:
        assert migrations.current(conn) == HEAD
        assert conn.exec_driver_sql("SELECT count(*) FROM alembic_version").scalar() == 1
        assert conn.exec_driver_sql("SELECT count(*) FROM secrets").scalar() == 1
    assert differences(boards[0].engine) == []
    for b in boards:
        b.close()
