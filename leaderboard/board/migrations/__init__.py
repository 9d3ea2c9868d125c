"""The hosted board's schema migrations (Alembic): :func:`upgrade` brings a board database to the head revision.

The revisions are in ``versions/``, from the first schema on; a database made before
the board used Alembic is recognised by its tables and stamped with its revision first.
See docs/leaderboard.md, "The database and its migrations".
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from importlib import resources

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from sqlalchemy.engine import Connection, Engine

FIRST = "0001"  # the schema of issue #34: the board's first
PER_ACCOUNT = "0002"  # issue #42: dedupe per account, fault/kind/spent_s/withdrawn, board_meta
LOCK_KEY = 0x77666265  # PostgreSQL advisory lock: one process migrates at a time ("wfbe")


class MigrationError(Exception):
    """A migration left the database inconsistent (it was rolled back)."""


class NewerBoardError(MigrationError):
    """The database is at a revision these migrations do not know: a newer wfbench wrote it."""

    def __init__(self, revision: str, head: str):
        super().__init__(f"board schema {revision} was written by a newer wfbench (this one reads up to {head}); "
                         "upgrade wfbench to open it")
        self.revision, self.head = revision, head


def config(connection: Connection | None = None, metadata: sa.MetaData | None = None) -> Config:
    """Alembic's configuration of the board: these revisions, run on ``connection`` (compared with ``metadata``)."""
    cfg = Config()
    cfg.set_main_option("script_location", str(resources.files(__name__)).replace("%", "%%"))
    cfg.attributes["connection"] = connection
    cfg.attributes["metadata"] = metadata
    return cfg


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Bring the database to ``revision`` in one transaction; safe to call on every start, by several processes.

    PostgreSQL: the transaction holds an advisory lock, so a second process waits and then
    finds nothing to do. SQLite: ``BEGIN IMMEDIATE`` does the same, and foreign keys are
    off while a table is rebuilt and checked before the commit (:class:`MigrationError`).
    """
    with _transaction(engine) as conn:
        check_known(conn)
        legacy = pre_alembic_revision(conn)
        if legacy is not None:
            command.stamp(config(conn), legacy)
        command.upgrade(config(conn), revision)
        if conn.dialect.name == "sqlite":
            broken = conn.exec_driver_sql("PRAGMA foreign_key_check").fetchall()
            if broken:
                raise MigrationError(f"migrating the board's database broke {len(broken)} foreign keys; nothing "
                                     "was changed")


def current(conn: Connection) -> str | None:
    """The revision the database is at (None: not under Alembic)."""
    from alembic.runtime.migration import MigrationContext

    return MigrationContext.configure(conn).get_current_revision()


def check_known(conn: Connection) -> None:
    """:class:`NewerBoardError` if the database is at a revision these migrations do not have."""
    from alembic.script import ScriptDirectory
    from alembic.util import CommandError

    revision = current(conn)
    if revision is None:
        return
    script = ScriptDirectory.from_config(config(conn))
    try:
        script.get_revision(revision)
    except CommandError:
        raise NewerBoardError(revision, script.get_current_head()) from None


def pre_alembic_revision(conn: Connection) -> str | None:
    """The revision of a board made before Alembic (by its tables), or None: under Alembic already, or empty."""
    tables = sa.inspect(conn)
    if tables.has_table("alembic_version") or not tables.has_table("submissions"):
        return None
    columns = {c["name"] for c in tables.get_columns("submissions")}
    return PER_ACCOUNT if "fault" in columns else FIRST


@contextmanager
def _transaction(engine: Engine) -> Iterator[Connection]:
    with engine.connect() as conn:
        sqlite = conn.dialect.name == "sqlite"
        if sqlite:  # outside any transaction, where SQLite honours it
            conn.connection.driver_connection.execute("PRAGMA foreign_keys=OFF")
        try:
            with conn.begin():
                if not sqlite:
                    conn.execute(sa.select(sa.func.pg_advisory_xact_lock(LOCK_KEY)))
                yield conn
        finally:
            if sqlite:
                conn.connection.driver_connection.execute("PRAGMA foreign_keys=ON")
