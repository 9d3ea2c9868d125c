"""The hosted leaderboard's database: accounts, packages, submissions, the job queue and the result rows.

One schema (SQLAlchemy Core) for SQLite, the default, and PostgreSQL, for workers on more than
one host (:func:`connect`). On SQLite every transaction is ``BEGIN IMMEDIATE`` (one writer at a
time, which makes the queue's claims and fences safe there); on PostgreSQL the queue locks rows
and a submission locks its account's row, so two uploads cannot both pass its quota.
:class:`Board` is the API. The schema changes through Alembic revisions
(:mod:`~wfbench.leaderboard.board.migrations`), which :meth:`Board.create` runs on every start: a
change to these tables needs a revision. What each table holds: ``docs/leaderboard.md``, "The
database and its migrations".
"""

from __future__ import annotations

import hashlib
import json
import math
import secrets as _secrets
import sqlite3
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pandas as pd
import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine
from wfbench.leaderboard.board import hidden, migrations
from wfbench.leaderboard.rows import BUDGET_ROW_COLUMNS, KPI_COLUMNS, RESULT_FRAME_COLUMNS, ROW_COLUMNS, check_rows
from wfbench.leaderboard.tracks import TRACKS, Track

from wfbench import __version__
from wfbench.harness.budget import BUDGET_COLUMNS

DEFAULT_DAILY_QUOTA = 5  # test-phase submissions per account per 24 h
DEV_DAILY_QUOTA = 10  # dev-phase submissions per account per 24 h
DEV_CONCURRENT = 2  # dev-phase jobs queued or running at once per account (the test phase: 1)
QUOTA_WINDOW_S = 24 * 3600.0
LOG_BYTES = 64 * 1024  # what is kept of a submission's log (its end)
STATES = ("queued", "running", "done", "failed")
SHOWN = {"queued": "running", "running": "running", "done": "complete", "failed": "failed", "withdrawn": "withdrawn"}
"""A submission's state as both boards' reports show it (:attr:`Submission.status`): queued and running alike."""
KEY_SECRET = "key_secret"
URL_FORMS = ("a file path or sqlite:///PATH (SQLite), or postgresql+psycopg://USER:PASSWORD@HOST[:PORT]/DB "
             "(PostgreSQL)")


BUILTIN_ACCOUNT = "wfbench"  # the admin account the built-ins are entered under (wfbench serve seed)


def _reserved_names() -> frozenset[str]:
    """The names only the built-ins' account may submit under: every registered policy's."""
    from wfbench.policies import names

    return frozenset(names())


FAILURE_KINDS = ("raised", "timed out", "out of memory", "bad action", "package refused", "board fault")
"""What a test-phase failure shows until the phase ends: one of these words, never the policy's own text."""
BOARD_FAULT = "board fault"
FAULTS = ("policy", "board")  # whose failure it is: the policy's is final, the board's is queued again


def kind_of_reason(reason: str) -> str:
    """The word of :data:`FAILURE_KINDS` for a policy's one-line failure ``reason``.

    The sandbox's and the guard's own phrasings decide: a time limit, memory, a
    malformed action; anything else the policy did is "raised". The policy can word its
    own exception to pick another of these words, but never to say anything else.
    """
    text = reason.lower()
    if "took longer than" in text or "act timeout" in text or "time budget" in text or "cpu limit" in text:
        return "timed out"
    if "memoryerror" in text or "memory limit" in text or "out of memory" in text:
        return "out of memory"
    if "malformed action" in text:
        return "bad action"
    return "raised"


def failure_kind(exc: BaseException) -> str:
    """The word of :data:`FAILURE_KINDS` for an exception that failed a submission (the policy's or its package's)."""
    if any(k.__name__ == "PackageError" for k in type(exc).__mro__):
        return "package refused"
    reason = getattr(exc, "reason", None) or getattr(exc, "message", None) or str(exc)
    return kind_of_reason(str(reason))


class BoardError(Exception):
    """A request the board cannot carry out (unknown track, bad name, unknown package): one line for the user."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


class QuotaExceeded(BoardError):
    """A submission over the account's quota of its phase (jobs at once, so many a day): the server's 429."""


class NotFound(BoardError):
    """No submission of that id: the server's 404."""


class NotYours(BoardError):
    """Another account's submission: the server's 403."""


# -- the schema -----------------------------------------------------------------------------------------------

metadata = sa.MetaData()

accounts = sa.Table(
    "accounts", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("name", sa.String(100), nullable=False, unique=True),
    sa.Column("token_hash", sa.String(64), nullable=False, unique=True),  # sha256 hex of the token
    sa.Column("admin", sa.Boolean, nullable=False, default=False),
    sa.Column("created", sa.Double, nullable=False),  # epoch seconds, as every time in this schema
)

packages = sa.Table(
    "packages", metadata,
    sa.Column("sha256", sa.String(71), primary_key=True),  # "sha256:<hex>"
    sa.Column("bytes", sa.LargeBinary, nullable=False),
    sa.Column("size", sa.BigInteger, nullable=False),
    sa.Column("created", sa.Double, nullable=False),
)

hidden_seeds = sa.Table(
    "hidden_seeds", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("track", sa.String(100), nullable=False),
    sa.Column("track_hash", sa.String(64), nullable=False),
    sa.Column("version", sa.Integer, nullable=False),
    sa.Column("seeds", sa.Text, nullable=False),  # JSON list of ints
    sa.Column("salt", sa.String(64), nullable=False),
    sa.Column("commitment", sa.String(71), nullable=False),  # published from the start
    sa.Column("created", sa.Double, nullable=False),
    sa.UniqueConstraint("track", "version"),
)

secrets_table = sa.Table(
    "secrets", metadata,
    sa.Column("name", sa.String(100), primary_key=True),
    sa.Column("value", sa.String(200), nullable=False),
)

board_meta = sa.Table(
    "board_meta", metadata,
    sa.Column("name", sa.String(100), primary_key=True),  # test_ended:TRACK (and schema_version before Alembic)
    sa.Column("value", sa.String(200), nullable=False),
)

submissions = sa.Table(
    "submissions", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("account_id", sa.Integer, sa.ForeignKey("accounts.id"), nullable=False),
    sa.Column("track", sa.String(100), nullable=False),
    sa.Column("track_hash", sa.String(64), nullable=False),
    sa.Column("phase", sa.String(8), nullable=False),
    sa.Column("package_sha", sa.String(71), sa.ForeignKey("packages.sha256"), nullable=False),
    sa.Column("entry", sa.String(300), nullable=False),
    sa.Column("name", sa.String(100), nullable=False),
    sa.Column("state", sa.String(8), nullable=False),
    sa.Column("reason", sa.Text, nullable=False, default=""),
    sa.Column("created", sa.Double, nullable=False),
    sa.Column("updated", sa.Double, nullable=False),
    sa.Column("attempts", sa.Integer, nullable=False, default=0),
    sa.Column("hidden_version", sa.Integer, nullable=True),  # the test phase's hidden seed list
    sa.Column("log", sa.Text, nullable=False, default=""),
    sa.Column("result", sa.Text, nullable=True),  # JSON aggregate, once done
    # issue #42 (schema version 2): whose failure, its word, the worker time used, the owner's withdrawal
    sa.Column("fault", sa.String(8), nullable=False, default="", server_default=""),  # "", policy, board
    sa.Column("kind", sa.String(20), nullable=False, default="", server_default=""),  # a FAILURE_KINDS word
    sa.Column("spent_s", sa.Double, nullable=False, default=0.0, server_default="0"),
    sa.Column("withdrawn", sa.Double, nullable=True),  # when its owner withdrew it; NULL: on the board
    # issue #54 (revision 0003): what a local entry records beyond the hosted columns ("" / false on a hosted board)
    sa.Column("builtin", sa.Boolean, nullable=False, default=False, server_default=sa.false()),
    sa.Column("fingerprint", sa.String(16), nullable=False, default="", server_default=""),  # "": before them
    sa.Column("fingerprint_detail", sa.Text, nullable=False, default="", server_default=""),
    sa.Column("budget", sa.Text, nullable=False, default="", server_default=""),  # JSON: the policy's stated cost
    sa.Column("wfbench_version", sa.String(40), nullable=False, default="", server_default=""),
    sa.Column("created_at", sa.String(40), nullable=False, default="", server_default=""),  # ISO time of a local one
    # once a local entry is off the board: replaced or withdrawn, why, when, and its place in the audit trail
    sa.Column("audit_action", sa.String(10), nullable=False, default="", server_default=""),
    sa.Column("audit_note", sa.Text, nullable=False, default="", server_default=""),
    sa.Column("audit_at", sa.String(40), nullable=False, default="", server_default=""),
    sa.Column("audit_id", sa.Integer, nullable=True),
    sa.CheckConstraint("phase IN ('dev', 'test')", name="phase_known"),
    sa.CheckConstraint("state IN ('queued', 'running', 'done', 'failed')", name="state_known"),
    sa.UniqueConstraint("account_id", "package_sha", "entry", "track", "phase", name="same_package_per_account"),
)
sa.Index("submissions_account", submissions.c.account_id, submissions.c.phase, submissions.c.created)

jobs = sa.Table(
    "jobs", metadata,
    sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), primary_key=True),
    sa.Column("state", sa.String(8), nullable=False),
    sa.Column("lease_owner", sa.String(200), nullable=True),
    sa.Column("lease_until", sa.Double, nullable=True),
    sa.Column("fence", sa.BigInteger, nullable=False, default=0),  # +1 at every claim
    sa.Column("heartbeat_at", sa.Double, nullable=True),
    sa.CheckConstraint("state IN ('queued', 'running', 'done', 'failed')", name="job_state_known"),
)
sa.Index("jobs_state", jobs.c.state, jobs.c.lease_until)

_COUNTS = ("episode_length", "invalid_actions")
PROVENANCE_COLUMNS = {"track": 100, "track_hash": 64, "policy": 300, "submitter": 100, "fingerprint": 16,
                      "wfbench_version": 40, "finished_at": 40, "digest": 64}
"""A local row's provenance (column: its length), which :func:`~wfbench.leaderboard.rows.row_digest` covers."""
rows = sa.Table(
    "rows", metadata,
    sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), nullable=False),
    sa.Column("scenario", sa.String(100), nullable=False),  # "" on a one-scenario track
    sa.Column("seed_index", sa.Integer, nullable=False),
    sa.Column("seed", sa.BigInteger, nullable=False),  # the real seed: never served for a test-phase submission
    *(sa.Column(c, sa.Double, nullable=False) for c in KPI_COLUMNS),
    *(sa.Column(c, sa.Integer, nullable=False) for c in _COUNTS),
    *(sa.Column(c, sa.Double, nullable=True) for c in BUDGET_COLUMNS),
    sa.Column("machine", sa.Text, nullable=True),
    sa.Column("finished", sa.Double, nullable=False),
    # issue #54 (revision 0003): a local entry's row carries its provenance and the digest over it; NULL otherwise
    *(sa.Column(c, sa.String(n), nullable=True) for c, n in PROVENANCE_COLUMNS.items()),
    sa.UniqueConstraint("submission_id", "scenario", "seed_index", name="one_row_per_unit"),
)
ROW_FIELDS = ("scenario", "seed_index", "seed", *ROW_COLUMNS, *BUDGET_ROW_COLUMNS)
"""The keys of a row as :func:`wfbench.leaderboard.board.queue.write_rows` takes it."""


# -- connecting -----------------------------------------------------------------------------------------------


def connect(url: str | Path) -> Engine:
    """An engine for a board database.

    Args:
        url: a file path or ``sqlite:///PATH`` (SQLite: WAL, a 30 s busy timeout,
            foreign keys on, every transaction ``BEGIN IMMEDIATE``), or
            ``postgresql+psycopg://USER:PASSWORD@HOST[:PORT]/DB`` (used as it is).

    Raises:
        BoardError: any other form (the message names the allowed ones), or an
            in-memory SQLite database (each connection would see another, empty one).
    """
    text = str(url)
    if "://" not in text:
        if not text or text == ":memory:":
            raise BoardError(f"database {text!r} is not allowed; allowed: {URL_FORMS}")
        return _sqlite(Path(text))
    try:
        parsed = sa.engine.make_url(text)
    except sa.exc.ArgumentError:
        raise BoardError(f"database URL {text!r} cannot be read; allowed: {URL_FORMS}") from None
    shown = parsed.render_as_string(hide_password=True)
    if parsed.drivername in ("sqlite", "sqlite+pysqlite"):
        if not parsed.database or parsed.database == ":memory:":
            raise BoardError(f"database {shown!r} is not allowed (in memory, or no file); allowed: {URL_FORMS}")
        return _sqlite(Path(parsed.database))
    if parsed.drivername == "postgresql+psycopg":
        # a client stopped inside a transaction (a worker paused past its lease) would hold its row locks, and every
        # other worker's claim skips locked jobs: the server ends such a session after IDLE_IN_TRANSACTION_MS
        return sa.create_engine(parsed, pool_pre_ping=True,
                                connect_args={"options": f"-c idle_in_transaction_session_timeout="
                                                         f"{IDLE_IN_TRANSACTION_MS}"})
    raise BoardError(f"database {shown!r} is not allowed; allowed: {URL_FORMS}")


BUSY_S = 30.0  # SQLite: how long a connection waits for another's lock
IDLE_IN_TRANSACTION_MS = 10_000  # PostgreSQL: a board transaction is a few statements; 10 s idle is a stalled client


def _sqlite(path: Path) -> Engine:
    if path.is_dir():
        raise BoardError(f"database {str(path)!r} is a folder; allowed: {URL_FORMS}")
    path.parent.mkdir(parents=True, exist_ok=True)
    engine = sa.create_engine(f"sqlite:///{path}", connect_args={"timeout": BUSY_S})

    @sa.event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN itself (below), not the sqlite3 module
        cur = dbapi_connection.cursor()
        cur.execute(f"PRAGMA busy_timeout={int(BUSY_S * 1000)}")
        _to_wal(cur)
        for pragma in ("foreign_keys=ON", "synchronous=FULL"):
            cur.execute(f"PRAGMA {pragma}")
        cur.close()

    @sa.event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")  # the write lock from the start: one writer, no upgrade deadlock

    return engine


def _to_wal(cur: Any) -> None:
    """``PRAGMA journal_mode=WAL``, waiting out another connection's lock as every other statement does.

    Switching a new database to WAL takes an exclusive lock, and SQLite answers "database is
    locked" at once, without its busy handler, while another connection holds one: several
    servers and workers opening an empty board together failed so under load. Once the file
    is in WAL mode (it stays so) the pragma is a no-op.
    """
    deadline = time.monotonic() + BUSY_S
    while True:
        try:
            cur.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


def is_sqlite(engine: Engine) -> bool:
    return engine.dialect.name == "sqlite"


# -- records --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Account:
    id: int
    name: str
    admin: bool
    created: float


@dataclass(frozen=True)
class Submission:
    """A hosted submission as stored; ``log`` is for the dev phase's page only, ``result`` the aggregate."""

    id: int
    account_id: int
    account: str  # the account's name
    track: str
    track_hash: str
    phase: str
    package_sha: str
    entry: str
    name: str
    state: str  # queued | running | done | failed
    reason: str  # one line; "" unless failed
    created: float
    updated: float
    attempts: int
    hidden_version: int | None
    log: str
    result: dict[str, Any] | None
    note: str = ""  # one line while it waits for a worker after losing one or a board fault; "" otherwise
    fault: str = ""  # "policy" or "board" for a failure (or a board fault it is queued again after); "" otherwise
    kind: str = ""  # the failure's word of FAILURE_KINDS; "" otherwise
    spent_s: float = 0.0  # worker seconds it used, over every attempt
    withdrawn: float | None = None  # when its owner withdrew it (state "withdrawn")
    builtin: bool = False  # one of wfbench's own entries (the local board's built-ins)
    # what identifies the policy: a local entry's fingerprint ("" for one stored before fingerprints), a package's
    # first 16 hex digits on a hosted board; and what it covers (JSON)
    fingerprint: str = ""
    fingerprint_detail: str = ""
    budget: str = ""  # JSON: what the policy states about its cost; "" where not recorded

    @property
    def status(self) -> str:
        """Its state as the reports show it (:data:`SHOWN`): ``running`` (queued too), ``complete`` or ``failed``."""
        return SHOWN[self.state]

    @property
    def local(self) -> bool:
        """An entry of the local board: the test phase on the track's published seeds (no hidden seed list)."""
        return self.phase == "test" and self.hidden_version is None

    @property
    def legacy(self) -> bool:
        """A local entry stored before fingerprints."""
        return self.local and not self.fingerprint


TOKEN_PREFIX = "wfb_"  # a token never starts with '-', which a command line would read as an option


def new_token() -> str:
    """A fresh account token: ``wfb_`` and 43 url-safe characters (256 random bits)."""
    return TOKEN_PREFIX + _secrets.token_urlsafe(32)


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def package_sha(data: bytes) -> str:
    """The content hash of a package, ``sha256:<hex>`` (as :func:`wfbench.harness.isolation.package.content_hash`)."""
    return "sha256:" + hashlib.sha256(data).hexdigest()


def cap_log(text: str, limit: int = LOG_BYTES) -> str:
    """The end of ``text`` within ``limit`` bytes of UTF-8, saying how much was cut."""
    data = text.encode("utf-8", "replace")
    if len(data) <= limit:
        return text
    return f"[... {len(data) - limit} bytes cut ...]\n" + data[-limit:].decode("utf-8", "ignore")


def _check_line(what: str, value: str, limit: int) -> str:
    if not isinstance(value, str) or not value.strip() or len(value) > limit or any(c in value for c in "\n\r\t\0"):
        raise BoardError(f"{what} {value!r} is not allowed; allowed: 1-{limit} characters on one line")
    return value


LOST = "lost its worker"  # how the queue's reason for a job it gave up on starts (queue.claim)


def _runs_again(r: Mapping[str, Any]) -> bool:
    """A submission that runs again when its owner submits the same bytes: withdrawn, or failed by the board.

    A board's failure (the sandbox did not start, a full disk, workers lost past the
    attempt limit) says nothing about the policy; the rows already stored are kept and
    the next worker runs only the missing ones. A database made before issue #42 marks
    a lost job by its reason only.
    """
    if r["withdrawn"] is not None:
        return True
    return r["state"] == "failed" and (r["fault"] == "board" or str(r["reason"]).startswith(LOST))


def _sub(r: Mapping[str, Any]) -> Submission:
    """The submission of a row of :data:`_SUBMISSION_QUERY`, its state as true as the lease says.

    A job whose worker stopped renewing its lease is not running any more: until another
    worker claims it (:func:`~wfbench.leaderboard.board.queue.claim`), it is shown as
    queued, with a note saying which worker was lost and when. A job put back after a
    board fault says so too. A withdrawn submission's state is ``withdrawn``.
    """
    state, note = r["state"], ""
    lease_until = r.get("lease_until")
    if state == "running" and lease_until is not None and lease_until < time.time():
        when = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(lease_until))
        state = "queued"
        note = (f"its worker {r.get('lease_owner') or '?'} stopped answering (lease ended {when}); the next worker "
                f"resumes it with the episodes still missing (attempt {r['attempts'] + 1} of at most {MAX_ATTEMPTS})")
    elif state == "queued" and r["fault"] == "board":
        note = (f"attempt {r['attempts']} of at most {MAX_ATTEMPTS} stopped on a board fault, not the policy's; the "
                "next worker resumes it with the episodes still missing")
    if r["withdrawn"] is not None:
        state, note = "withdrawn", ""
    fingerprint, detail = r["fingerprint"], r["fingerprint_detail"]
    if not (r["phase"] == "test" and r["hidden_version"] is None):  # a package's: its hash names it
        fingerprint = r["package_sha"].removeprefix("sha256:")[:16]
        detail = json.dumps({"package": r["package_sha"], "entry": r["entry"]})
    return Submission(r["id"], r["account_id"], r["account"], r["track"], r["track_hash"], r["phase"],
                      r["package_sha"], r["entry"], r["name"], state, r["reason"], r["created"], r["updated"],
                      r["attempts"], r["hidden_version"], r["log"], json.loads(r["result"]) if r["result"] else None,
                      note, r["fault"], r["kind"], float(r["spent_s"] or 0.0), r["withdrawn"], bool(r["builtin"]),
                      fingerprint, detail, r["budget"])


def submissions_where(conn: Connection, where: Any) -> list[Submission]:
    """The submissions ``where`` selects, oldest first, inside the caller's transaction."""
    return [_sub(r) for r in conn.execute(_SUBMISSION_QUERY.where(where).order_by(submissions.c.id)).mappings()]


MAX_ATTEMPTS = 3  # claims of one job before the queue gives up on it (queue.claim)

_SUBMISSION_QUERY = (sa.select(submissions, accounts.c.name.label("account"), jobs.c.lease_until, jobs.c.lease_owner)
                     .join(accounts, accounts.c.id == submissions.c.account_id)
                     .outerjoin(jobs, jobs.c.submission_id == submissions.c.id))


def _hidden(r: Mapping[str, Any]) -> hidden.HiddenSeeds:
    return hidden.HiddenSeeds(r["track"], r["track_hash"], r["version"], tuple(json.loads(r["seeds"])), r["salt"],
                              r["commitment"], r["created"])


# -- the board ------------------------------------------------------------------------------------------------


class Board:
    """A hosted leaderboard's database.

    Args:
        url: the database (:func:`connect`).
        tracks: the tracks submissions may name (default: every track of
            :data:`wfbench.leaderboard.tracks.TRACKS`), by name.
        daily_quota: test-phase submissions per account per 24 h (one queued or running at a time).
        dev_daily_quota: development-phase submissions per account per 24 h.
        dev_concurrent: development-phase jobs queued or running at once per account.
    """

    def __init__(self, url: str | Path, tracks: Mapping[str, Track] | None = None,
                 daily_quota: int = DEFAULT_DAILY_QUOTA, dev_daily_quota: int = DEV_DAILY_QUOTA,
                 dev_concurrent: int = DEV_CONCURRENT):
        for what, value in (("daily quota", daily_quota), ("dev-phase quota", dev_daily_quota),
                            ("dev-phase jobs at once", dev_concurrent)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise BoardError(f"{what} {value!r} is not allowed; allowed: 1 or more")
        self.url = str(url)
        self.engine = connect(url)
        self.tracks: dict[str, Track] = dict(TRACKS if tracks is None else tracks)
        self.daily_quota = daily_quota
        # phase -> (jobs queued or running at once, submissions per 24 h)
        self.quotas = {"test": (1, daily_quota), "dev": (dev_concurrent, dev_daily_quota)}

    def close(self) -> None:
        """Close the database connections."""
        self.engine.dispose()

    def create(self) -> None:
        """Bring the schema to the head revision and make the key secret where there is none (safe on every start).

        An empty database gets every revision; one made by an earlier wfbench is upgraded in
        place, in one transaction, whoever starts first (server or worker); see
        :func:`wfbench.leaderboard.board.migrations.upgrade`.
        """
        try:
            migrations.upgrade(self.engine)
        except migrations.MigrationError as exc:
            raise BoardError(str(exc)) from None
        try:
            with self.engine.begin() as conn:
                if conn.execute(sa.select(secrets_table.c.name).where(secrets_table.c.name == KEY_SECRET)).first() \
                        is None:
                    conn.execute(secrets_table.insert().values(name=KEY_SECRET, value=_secrets.token_hex(32)))
        except sa.exc.IntegrityError:  # another process made it at the same time
            pass

    def track(self, name: str) -> Track:
        """The track ``name``, or BoardError naming those there are."""
        if name not in self.tracks:
            raise BoardError(f"unknown track {name!r}; available: {', '.join(self.tracks)}")
        return self.tracks[name]

    # -- accounts ---------------------------------------------------------------------------------------------
    def add_account(self, name: str, admin: bool = False) -> str:
        """Make an account and return its token: shown this once, stored only as its sha256."""
        _check_line("account name", name, 100)
        token = new_token()
        try:
            with self.engine.begin() as conn:
                conn.execute(accounts.insert().values(name=name, token_hash=token_hash(token), admin=bool(admin),
                                                      created=time.time()))
        except sa.exc.IntegrityError:
            raise BoardError(f"account name {name!r} is taken; choose another") from None
        return token

    def account(self, token: str) -> Account | None:
        """The account whose token this is, or None (a wrong or empty token)."""
        if not token:
            return None
        with self.engine.begin() as conn:
            r = conn.execute(sa.select(accounts).where(accounts.c.token_hash == token_hash(token))).mappings().first()
        return Account(r["id"], r["name"], bool(r["admin"]), r["created"]) if r else None

    def account_by_name(self, name: str) -> Account | None:
        """The account called ``name``, or None."""
        with self.engine.begin() as conn:
            r = conn.execute(sa.select(accounts).where(accounts.c.name == name)).mappings().first()
        return Account(r["id"], r["name"], bool(r["admin"]), r["created"]) if r else None

    # -- packages ---------------------------------------------------------------------------------------------
    def put_package(self, data: bytes) -> str:
        """Store a package's bytes once per content hash and return the hash (``sha256:<hex>``)."""
        sha = package_sha(data)
        try:
            with self.engine.begin() as conn:
                if conn.execute(sa.select(packages.c.sha256).where(packages.c.sha256 == sha)).first() is None:
                    conn.execute(packages.insert().values(sha256=sha, bytes=data, size=len(data), created=time.time()))
        except sa.exc.IntegrityError:  # the same bytes stored at the same time by another upload
            pass
        return sha

    def package(self, sha: str) -> bytes | None:
        """A stored package's bytes, or None."""
        with self.engine.begin() as conn:
            return conn.execute(sa.select(packages.c.bytes).where(packages.c.sha256 == sha)).scalar()

    # -- submissions ------------------------------------------------------------------------------------------
    def submit(self, account: Account, track: str, phase: str, package_sha: str, entry: str,
               name: str, quota: bool = True) -> tuple[Submission, bool]:
        """Queue a package's evaluation, or return the account's submission of the same package already made.

        The same (account, package, entry, track, phase) returns the existing submission
        with ``created`` False: it is not evaluated twice and not counted against a quota.
        Another account's identical bytes are that account's own submission. Two
        exceptions run again (``created`` True, the rows already stored kept): a
        submission the board failed (:data:`FAULTS` "board": the sandbox did not start, a
        full disk, its workers lost past the attempt limit) and a withdrawn one. A new
        submission needs the account within its phase's quota (:attr:`quotas`: jobs
        queued or running at once, submissions per 24 h); ``quota=False`` skips that
        check (the operator's built-ins, :mod:`.seed`, never reachable from the web
        server). No test-phase submission is taken once the track's test phase ended.

        Raises:
            BoardError: unknown track or phase, a bad name or entry, an unknown package,
                a test phase that ended.
            QuotaExceeded: over the phase's quota (the reason says which and until when).
        """
        tr = self.track(track)
        try:
            hidden.check_phase(phase)
        except ValueError as exc:
            raise BoardError(str(exc)) from None
        _check_line("submission name", name, 100)
        if name in _reserved_names() and account.name != BUILTIN_ACCOUNT:
            # the reports find the baseline (heuristic) and the built-ins by name: a namesake would hide them
            raise BoardError(f"the name {name!r} is kept for the built-in entry of that policy; allowed: any other "
                             f"name (--name)")
        _check_line("entry point", entry, 300)
        version = self.ensure_hidden_seeds(track).version if phase == "test" else None
        key = ((submissions.c.account_id == account.id) & (submissions.c.package_sha == package_sha)
               & (submissions.c.entry == entry) & (submissions.c.track == track) & (submissions.c.phase == phase))
        try:
            with self.engine.begin() as conn:
                # one submission at a time per account (PostgreSQL; SQLite's BEGIN IMMEDIATE already serializes)
                conn.execute(sa.select(accounts.c.id).where(accounts.c.id == account.id).with_for_update())
                existing = conn.execute(_SUBMISSION_QUERY.where(key)).mappings().first()
                if existing is not None and not _runs_again(existing):
                    return _sub(existing), False
                if phase == "test":
                    self._check_open(conn, track)
                now = time.time()
                if quota:
                    self._check_quota(conn, account, phase, now)
                if existing is not None:  # failed by the board or withdrawn, not failed by the policy: run again
                    conn.execute(submissions.update().where(submissions.c.id == existing["id"]).values(
                        state="queued", reason="", fault="", kind="", attempts=0, withdrawn=None, updated=now))
                    conn.execute(jobs.update().where(jobs.c.submission_id == existing["id"]).values(
                        state="queued", lease_owner=None, lease_until=None, fence=jobs.c.fence + 1))
                    again = conn.execute(_SUBMISSION_QUERY.where(submissions.c.id == existing["id"])).mappings().one()
                    return _sub(again), True
                if conn.execute(sa.select(packages.c.size).where(packages.c.sha256 == package_sha)).first() is None:
                    raise BoardError(f"no package {package_sha!r} on this board; upload the package first")
                sub_id = conn.execute(submissions.insert().values(
                    account_id=account.id, track=track, track_hash=tr.hash, phase=phase, package_sha=package_sha,
                    entry=entry, name=name, state="queued", reason="", created=now, updated=now, attempts=0,
                    hidden_version=version, log="", result=None, fault="", kind="", spent_s=0.0,
                    withdrawn=None)).inserted_primary_key[0]
                conn.execute(jobs.insert().values(submission_id=sub_id, state="queued", fence=0))
        except sa.exc.IntegrityError:  # the same package submitted by the same account at the same moment
            with self.engine.begin() as conn:
                existing = conn.execute(_SUBMISSION_QUERY.where(key)).mappings().first()
            if existing is None:
                raise
            return _sub(existing), False
        return self.submission(sub_id), True  # type: ignore[return-value]

    def _check_quota(self, conn: Connection, account: Account, phase: str, now: float) -> None:
        at_once, daily = self.quotas[phase]
        mine = (submissions.c.account_id == account.id) & (submissions.c.phase == phase)
        busy = conn.execute(sa.select(submissions.c.id, submissions.c.state).where(
            mine & submissions.c.state.in_(("queued", "running")) & submissions.c.withdrawn.is_(None))
            .order_by(submissions.c.id).limit(at_once)).all()
        if len(busy) >= at_once:
            if at_once == 1:
                raise QuotaExceeded(f"one {phase}-phase job at a time per account: submission {busy[0].id} is "
                                    f"still {busy[0].state}; submit again once it is done or failed")
            states = sorted({b.state for b in busy})
            raise QuotaExceeded(f"at most {at_once} {phase}-phase jobs queued or running at a time per account: "
                                f"submissions {', '.join(str(b.id) for b in busy)} are still "
                                f"{' or '.join(states)}; submit again once one is done or failed")
        recent = conn.execute(sa.select(submissions.c.created).where(
            mine & (submissions.c.created > now - QUOTA_WINDOW_S)).order_by(submissions.c.created)).scalars().all()
        if len(recent) >= daily:
            frees = recent[len(recent) - daily] + QUOTA_WINDOW_S
            at = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(frees))
            raise QuotaExceeded(f"daily quota reached: {len(recent)} {phase}-phase submissions in the last 24 h "
                                f"(allowed: {daily}); the next one is allowed in "
                                f"{max(1, math.ceil((frees - now) / 60))} min (at {at})")

    # -- the test phase's end -----------------------------------------------------------------------------------
    def end_test_phase(self, track: str) -> float:
        """End ``track``'s test phase (the board's administrator); when it ended (the first call's time).

        From then on no test submission is taken, and every reader sees the test-phase
        failures' whole reasons.
        """
        self.track(track)
        try:
            with self.engine.begin() as conn:
                conn.execute(board_meta.insert().values(name=f"test_ended:{track}", value=repr(time.time())))
        except sa.exc.IntegrityError:  # ended before
            pass
        ended = self.test_phase_ended(track)
        assert ended is not None
        return ended

    def test_phase_ended(self, track: str) -> float | None:
        """When ``track``'s test phase ended, or None while it runs."""
        with self.engine.begin() as conn:
            value = conn.execute(sa.select(board_meta.c.value).where(board_meta.c.name == f"test_ended:{track}")
                                 ).scalar()
        return float(value) if value is not None else None

    def _check_open(self, conn: Connection, track: str) -> None:
        value = conn.execute(sa.select(board_meta.c.value).where(board_meta.c.name == f"test_ended:{track}")).scalar()
        if value is not None:
            when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(float(value)))
            raise BoardError(f"the test phase of track {track} ended at {when}; allowed: the dev phase")

    def shown_reason(self, sub: Submission, admin: bool = False) -> str:
        """What a reader is shown of a failure's reason: the whole line, except in a running test phase.

        There, a reader other than the board's administrator sees only its word of
        :data:`FAILURE_KINDS` (:attr:`Submission.kind`): a policy must not pass anything
        it observed on the hidden seeds out through its exception's text. A local entry,
        which ran on the published seeds, shows its whole reason.
        """
        if not sub.reason or sub.phase != "test" or sub.local or admin or self.test_phase_ended(sub.track) is not None:
            return sub.reason
        return sub.kind or "raised"

    # -- an owner's submissions ---------------------------------------------------------------------------------
    def account_submissions(self, account: Account) -> list[Submission]:
        """``account``'s submissions, withdrawn ones included, oldest first."""
        with self.engine.begin() as conn:
            return [_sub(r) for r in conn.execute(_SUBMISSION_QUERY.where(submissions.c.account_id == account.id)
                                                  .order_by(submissions.c.id)).mappings()]

    def withdraw(self, account: Account, submission_id: int) -> Submission:
        """Take ``account``'s submission off the board and cancel its job (an admin may withdraw any).

        Its rows stay in the database; a worker running it has its next write refused
        (the job's fence moves on) and drops it. Withdrawing again changes nothing;
        submitting the same bytes again puts it back and runs what is missing.

        Raises:
            NotFound: no such submission.
            NotYours: another account's.
        """
        with self.engine.begin() as conn:
            r = conn.execute(_SUBMISSION_QUERY.where(submissions.c.id == submission_id)).mappings().first()
            if r is None:
                raise NotFound(f"no submission {submission_id}")
            if r["account_id"] != account.id and not account.admin:
                raise NotYours(f"submission {submission_id} is not yours; allowed: withdrawing your own submissions "
                               "(GET /api/submissions lists them)")
            if r["withdrawn"] is None:
                now = time.time()
                values: dict[str, Any] = {"withdrawn": now, "updated": now}
                if r["state"] in ("queued", "running"):
                    values.update(state="failed", reason="withdrawn by its owner", fault="", kind="")
                conn.execute(submissions.update().where(submissions.c.id == submission_id).values(**values))
                conn.execute(jobs.update().where((jobs.c.submission_id == submission_id)
                                                 & jobs.c.state.in_(("queued", "running"))).values(
                    state="failed", lease_owner=None, lease_until=None, fence=jobs.c.fence + 1))
            r = conn.execute(_SUBMISSION_QUERY.where(submissions.c.id == submission_id)).mappings().one()
        return _sub(r)

    def submission(self, submission_id: int) -> Submission | None:
        """The submission ``submission_id``, or None."""
        with self.engine.begin() as conn:
            r = conn.execute(_SUBMISSION_QUERY.where(submissions.c.id == submission_id)).mappings().first()
        return _sub(r) if r else None

    def submissions(self, track: str | None = None, phase: str | None = None) -> list[Submission]:
        """The submissions of a track and phase (``None``: any), oldest first."""
        q = _SUBMISSION_QUERY
        if track is not None:
            q = q.where(submissions.c.track == track)
        if phase is not None:
            q = q.where(submissions.c.phase == phase)
        with self.engine.begin() as conn:
            return [_sub(r) for r in conn.execute(q.order_by(submissions.c.id)).mappings()]

    def rows(self, submission_id: int) -> pd.DataFrame:
        """A submission's stored rows, by scenario and seed index.

        Columns: ``scenario``, ``seed_index``, ``seed`` (only for a dev-phase submission: a
        test-phase one never shows its hidden seeds), the KPIs, ``episode_length``,
        ``invalid_actions``, the budget columns and ``machine``.
        """
        with self.engine.begin() as conn:
            phase = conn.execute(sa.select(submissions.c.phase).where(submissions.c.id == submission_id)).scalar()
            df = pd.read_sql_query(sa.select(*(rows.c[c] for c in ROW_FIELDS))
                                   .where(rows.c.submission_id == submission_id)
                                   .order_by(rows.c.scenario, rows.c.seed_index), conn)
        if phase != "dev":
            df = df.drop(columns="seed")
        return df.astype({c: float for c in BUDGET_COLUMNS})

    def done_units(self, submission_id: int) -> set[tuple[str, int]]:
        """The (scenario, seed index) pairs a submission has rows for (what a resumed job skips)."""
        with self.engine.begin() as conn:
            return {(r.scenario, r.seed_index) for r in conn.execute(
                sa.select(rows.c.scenario, rows.c.seed_index).where(rows.c.submission_id == submission_id))}

    def units(self, sub: Submission) -> list[tuple[str, int, int]]:
        """(scenario, seed index, seed) a submission runs, real seeds included: for the worker, never to be served.

        Raises:
            BoardError: the track is not on this board any more, its definition changed
                since the submission, or the hidden seed list it recorded is gone.
        """
        tr = self.track(sub.track)
        if tr.hash != sub.track_hash:
            raise BoardError(f"track {sub.track} changed since the submission (hash {sub.track_hash}, now {tr.hash}); "
                             "submit again to run on the current definition")
        h = None
        if sub.phase == "test":
            with self.engine.begin() as conn:
                r = conn.execute(sa.select(hidden_seeds).where((hidden_seeds.c.track == sub.track)
                                                               & (hidden_seeds.c.version == sub.hidden_version)
                                                               )).mappings().first()
            if r is None:
                raise BoardError(f"hidden seed list version {sub.hidden_version} of track {sub.track} is missing")
            h = _hidden(r)
        return hidden.units(tr, hidden.phase_seeds(tr, sub.phase, h))

    # -- hidden seeds and keys --------------------------------------------------------------------------------
    def ensure_hidden_seeds(self, track: str, n: int = hidden.DEFAULT_COUNT) -> hidden.HiddenSeeds:
        """The current hidden seed list of ``track`` (its latest version made on the track's current hash).

        The first call, and the first after the track's definition changed, draws a new list
        (the next version); later calls return it as stored, whatever ``n``.
        """
        tr = self.track(track)
        for _ in range(3):
            with self.engine.begin() as conn:
                latest = conn.execute(sa.select(hidden_seeds).where(hidden_seeds.c.track == track)
                                      .order_by(hidden_seeds.c.version.desc()).limit(1)).mappings().first()
                if latest is not None and latest["track_hash"] == tr.hash:
                    return _hidden(latest)
            made = hidden.make(tr, (latest["version"] if latest else 0) + 1, n, time.time())
            try:
                with self.engine.begin() as conn:
                    conn.execute(hidden_seeds.insert().values(
                        track=made.track, track_hash=made.track_hash, version=made.version,
                        seeds=json.dumps(list(made.seeds)), salt=made.salt, commitment=made.commitment,
                        created=made.created))
                return made
            except sa.exc.IntegrityError:  # another server process drew that version first: read it
                continue
        raise BoardError(f"could not store a hidden seed list for track {track}: too many concurrent attempts")

    def hidden_commitment(self, track: str) -> hidden.Commitment | None:
        """What is published of the track's current hidden seed list (no seeds, no salt), or None before any."""
        tr = self.track(track)
        with self.engine.begin() as conn:
            r = conn.execute(sa.select(hidden_seeds).where((hidden_seeds.c.track == track)
                                                           & (hidden_seeds.c.track_hash == tr.hash))
                             .order_by(hidden_seeds.c.version.desc()).limit(1)).mappings().first()
        return hidden.public(_hidden(r)) if r else None

    def key_secret(self) -> bytes:
        """The board's secret for the opaque per-episode keys (``isolation.sandbox.evaluate_sandboxed``)."""
        with self.engine.begin() as conn:
            value = conn.execute(sa.select(secrets_table.c.value).where(secrets_table.c.name == KEY_SECRET)).scalar()
        if value is None:
            raise BoardError("the board has no key secret: run Board.create() (wfbench serve does) first")
        return bytes.fromhex(value)

    # -- the board as the reports rank it ----------------------------------------------------------------------
    def phase_track(self, track: str, phase: str) -> Track:
        """The track a phase of ``track`` is ranked with: its ``test_seeds`` are what the phase's rows carry.

        The development phase ranks on the public seeds; the test phase on the hidden seeds
        by their index (:func:`~wfbench.leaderboard.board.hidden.board_track`), the list's
        commitment in the description: no hidden seed reaches a report. The local board
        ranks its entries on the track itself.
        """
        tr = self.track(track)
        try:
            hidden.check_phase(phase)
        except ValueError as exc:
            raise BoardError(str(exc)) from None
        h = self.hidden_commitment(track) if phase == "test" else None
        note = (f"test phase on {h.count} hidden seeds (version {h.version}, commitment {h.commitment}), shown by "
                "index" if h else "test phase on hidden seeds, none drawn yet") if phase == "test" \
            else "development phase on the public seeds"
        return hidden.board_track(tr, phase, h.count if h else 0, note)

    def entries(self, track: str, phase: str = "test") -> list[Submission]:
        """What the ranking lists of a phase of ``track``: the submissions on the board, oldest first.

        Each is named as the board shows it (:func:`entry_names`), its reason as a reader
        sees it (:meth:`shown_reason`). A submission the board evaluated from a package
        but made on another version of the track, or (test phase) on another hidden seed
        list, is left out; :meth:`results` says why.
        """
        return self._standing(track, phase)[0]

    def results(self, track: Track, phase: str = "test") -> tuple[pd.DataFrame, list[str]]:
        """The rows the ranking may use of a phase of ``track``, and one message per refused row or submission.

        The rows have :data:`~wfbench.leaderboard.rows.RESULT_FRAME_COLUMNS`, by entry, scenario
        and seed. A local entry's row is checked against ``track`` and its digest
        (:func:`~wfbench.leaderboard.rows.check_rows`). A hosted submission's rows are the
        board's own; in the test phase their ``seed`` is the seed's index in the hidden list
        (rank them with :meth:`phase_track`).
        """
        subs, refused = self._standing(track.name, phase)
        local = [s for s in subs if s.local]
        hosted = [s for s in subs if not s.local]
        frames = []
        if local:
            q = (sa.select(submissions.c.name, submissions.c.state, submissions.c.builtin, rows.c.submission_id,
                           rows.c.seed, *(rows.c[c] for c in PROVENANCE_COLUMNS if c not in ("finished_at", "digest")),
                           rows.c.finished_at, rows.c.digest, *(rows.c[c] for c in (*ROW_COLUMNS, *BUDGET_ROW_COLUMNS,
                                                                                     "scenario")))
                 .select_from(rows.join(submissions, submissions.c.id == rows.c.submission_id))
                 .where(submissions.c.id.in_([s.id for s in local]) & (rows.c.track == track.name))
                 .order_by(submissions.c.id, rows.c.scenario, rows.c.seed))
            with self.engine.begin() as conn:
                found = [{**d, "status": SHOWN[d.pop("state")]} for d in map(dict, conn.execute(q).mappings())]
            keep, bad = check_rows(found, track)
            refused += bad
            frames.append(pd.DataFrame(keep, columns=list(RESULT_FRAME_COLUMNS)))
        if hosted:
            frames.append(self._hosted_rows(track, phase, hosted))
        if len(frames) != 1:
            frames = [pd.concat(frames, ignore_index=True) if frames
                      else pd.DataFrame([], columns=list(RESULT_FRAME_COLUMNS))]
        return frames[0], refused

    def _standing(self, track: str, phase: str) -> tuple[list[Submission], list[str]]:
        """The submissions a ranking lists (named, reasons as shown) and why others of the phase are left out."""
        try:
            hidden.check_phase(phase)
        except ValueError as exc:
            raise BoardError(str(exc)) from None
        with self.engine.begin() as conn:
            subs = [_sub(r) for r in conn.execute(_SUBMISSION_QUERY.where(
                (submissions.c.track == track) & (submissions.c.phase == phase)
                & submissions.c.withdrawn.is_(None)).order_by(submissions.c.id)).mappings()]
        names = entry_names(subs)
        keep, refused = [], []
        current = None
        for s in subs:
            if not s.local:
                if current is None:
                    tr = self.track(track)
                    h = self.hidden_commitment(track) if phase == "test" else None
                    current = (tr.hash, h.version if h else None)
                if s.track_hash != current[0]:
                    refused.append(f"submission {s.id} ({names[s.id]!r}) was made on another version of track "
                                   f"{s.track} (hash {s.track_hash}, current {current[0]}); refused")
                    continue
                if phase == "test" and s.hidden_version != current[1]:
                    refused.append(f"submission {s.id} ({names[s.id]!r}) ran on hidden seed list version "
                                   f"{s.hidden_version}, not the current {current[1]}; refused")
                    continue
            keep.append(replace(s, name=names[s.id], reason=self.shown_reason(s)))
        return keep, refused

    def _hosted_rows(self, track: Track, phase: str, subs: list[Submission]) -> pd.DataFrame:
        """The rows of hosted submissions in the reports' columns (no digest: the board's own rows)."""
        by_id = {s.id: s for s in subs}
        with self.engine.begin() as conn:
            frame = pd.read_sql_query(sa.select(rows).where(rows.c.submission_id.in_(list(by_id)))
                                      .order_by(rows.c.submission_id, rows.c.scenario, rows.c.seed_index), conn)
        if phase == "test":
            frame["seed"] = frame["seed_index"]  # the index, never the hidden seed
        ids = frame["submission_id"]
        return pd.DataFrame({
            "name": [by_id[i].name for i in ids],
            "status": [by_id[i].status for i in ids],
            "builtin": False,
            "submission_id": ids.to_numpy(),
            "seed": frame["seed"].to_numpy(dtype=int),
            "track": track.name, "track_hash": track.hash,
            "policy": [by_id[i].entry for i in ids],
            "submitter": [by_id[i].account for i in ids],
            "wfbench_version": __version__, "finished_at": frame["finished"].to_numpy(),
            **{c: frame[c].to_numpy() for c in ROW_COLUMNS},
            "digest": "",
            "fingerprint": [by_id[i].fingerprint for i in ids],
            **{c: frame[c].to_numpy(dtype=float) for c in BUDGET_COLUMNS},
            "machine": frame["machine"].to_numpy(),
            "scenario": frame["scenario"].to_numpy(),
        }, index=pd.RangeIndex(len(frame)))


def entry_names(subs: list[Submission]) -> dict[int, str]:
    """The name each submission has on a board: its own, or ``NAME #ID`` where several share it."""
    count: dict[str, int] = {}
    for s in subs:
        count[s.name] = count.get(s.name, 0) + 1
    return {s.id: s.name if count[s.name] == 1 else f"{s.name} #{s.id}" for s in subs}
