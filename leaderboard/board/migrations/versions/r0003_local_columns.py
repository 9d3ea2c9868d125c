"""Issue #54: the local board's columns move into ``submissions`` and ``rows``; its own two tables go.

Until this revision the local board (``wfbench.leaderboard.store``) kept what only it
records in two tables that ``create_all`` made beside the board's, outside Alembic:
``local_entries`` (per entry: fingerprint, budget, built-in, version and time, and for
an entry off the board why, when and in what order) and ``local_rows`` (per row: its
provenance and digest). Their columns join ``submissions`` and ``rows``, every value
is copied over, and the two tables are dropped. A hosted board gains the columns with
their defaults (its rows: NULL) and changes in nothing else.
"""

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

# (name, type, server default) of each column a submission gains; every one NOT NULL but audit_id
SUBMISSION_COLUMNS = (
    ("builtin", sa.Boolean, sa.false()),
    ("fingerprint", sa.String(16), ""),
    ("fingerprint_detail", sa.Text, ""),
    ("budget", sa.Text, ""),
    ("wfbench_version", sa.String(40), ""),
    ("created_at", sa.String(40), ""),
    ("audit_action", sa.String(10), ""),
    ("audit_note", sa.Text, ""),
    ("audit_at", sa.String(40), ""),
)
# the columns of a row's provenance, all NULL on a hosted board's rows
ROW_COLUMNS = (
    ("track", sa.String(100)),
    ("track_hash", sa.String(64)),
    ("policy", sa.String(300)),
    ("submitter", sa.String(100)),
    ("fingerprint", sa.String(16)),
    ("wfbench_version", sa.String(40)),
    ("finished_at", sa.String(40)),
    ("digest", sa.String(64)),
)
# local_entries' columns by their name in submissions
ENTRY_MOVES = {"builtin": "builtin", "fingerprint": "fingerprint", "fingerprint_detail": "fingerprint_detail",
               "budget": "budget", "wfbench_version": "wfbench_version", "created_at": "created_at",
               "action": "audit_action", "note": "audit_note", "moved_at": "audit_at", "audit_id": "audit_id"}
ROW_KEY = ("submission_id", "scenario", "seed_index")


def upgrade() -> None:
    conn = op.get_bind()
    with op.batch_alter_table("submissions") as batch:
        for name, type_, default in SUBMISSION_COLUMNS:
            batch.add_column(sa.Column(name, type_, nullable=False, server_default=default))
        batch.add_column(sa.Column("audit_id", sa.Integer, nullable=True))
    with op.batch_alter_table("rows") as batch:
        for name, type_ in ROW_COLUMNS:
            batch.add_column(sa.Column(name, type_, nullable=True))
    if not sa.inspect(conn).has_table("local_entries"):  # a hosted board, or a local one made after this revision
        return
    entries = sa.table("local_entries", sa.column("submission_id"), *(sa.column(c) for c in ENTRY_MOVES))
    subs = sa.table("submissions", sa.column("id"), *(sa.column(c) for c in ENTRY_MOVES.values()))
    found = [dict(r) for r in conn.execute(sa.select(entries)).mappings()]
    if found:
        conn.execute(subs.update().where(subs.c.id == sa.bindparam("b_id")).values(
            {new: sa.bindparam(f"b_{old}") for old, new in ENTRY_MOVES.items()}),
            [{"b_id": r["submission_id"], **{f"b_{old}": r[old] for old in ENTRY_MOVES}} for r in found])
    names = [name for name, _ in ROW_COLUMNS]
    local = sa.table("local_rows", *(sa.column(c) for c in (*ROW_KEY, *names)))
    rows = sa.table("rows", *(sa.column(c) for c in (*ROW_KEY, *names)))
    found = [dict(r) for r in conn.execute(sa.select(local)).mappings()]
    if found:
        conn.execute(rows.update().where(sa.and_(*(rows.c[k] == sa.bindparam(f"b_{k}") for k in ROW_KEY))).values(
            {c: sa.bindparam(f"b_{c}") for c in names}),
            [{f"b_{c}": r[c] for c in (*ROW_KEY, *names)} for r in found])
    op.drop_table("local_rows")
    op.drop_table("local_entries")


def downgrade() -> None:
    """The columns go back into ``local_entries`` and ``local_rows`` (for the local entries and their rows)."""
    conn = op.get_bind()
    op.create_table(
        "local_entries",
        sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), primary_key=True),
        sa.Column("builtin", sa.Boolean, nullable=False),
        sa.Column("fingerprint", sa.String(16), nullable=False),
        sa.Column("fingerprint_detail", sa.Text, nullable=False),
        sa.Column("budget", sa.Text, nullable=False),
        sa.Column("wfbench_version", sa.String(40), nullable=False),
        sa.Column("created_at", sa.String(40), nullable=False),
        sa.Column("action", sa.String(10), nullable=False),
        sa.Column("note", sa.Text, nullable=False),
        sa.Column("moved_at", sa.String(40), nullable=False),
        sa.Column("audit_id", sa.Integer, nullable=True),
    )
    op.create_table(
        "local_rows",
        sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), nullable=False),
        sa.Column("scenario", sa.String(100), nullable=False),
        sa.Column("seed_index", sa.BigInteger, nullable=False),
        *(sa.Column(name, type_, nullable=False) for name, type_ in ROW_COLUMNS),
        sa.UniqueConstraint(*ROW_KEY, name="one_local_row_per_unit"),
    )
    names = [name for name, _ in ROW_COLUMNS]
    subs = sa.table("submissions", sa.column("id"), *(sa.column(c) for c in ENTRY_MOVES.values()))
    rows = sa.table("rows", *(sa.column(c) for c in (*ROW_KEY, *names)))
    local = rows.c.digest.is_not(None)  # a local entry's rows carry their digest
    entries = sa.table("local_entries", sa.column("submission_id"), *(sa.column(c) for c in ENTRY_MOVES))
    for r in conn.execute(sa.select(subs).where(subs.c.created_at != "")).mappings():  # a local entry has its time
        conn.execute(entries.insert().values(submission_id=r["id"], **{old: r[new] for old, new in
                                                                        ENTRY_MOVES.items()}))
    local_rows = sa.table("local_rows", *(sa.column(c) for c in (*ROW_KEY, *names)))
    for r in conn.execute(sa.select(rows).where(local)).mappings():
        conn.execute(local_rows.insert().values(**dict(r)))
    with op.batch_alter_table("rows") as batch:
        for name in reversed(names):
            batch.drop_column(name)
    with op.batch_alter_table("submissions") as batch:
        for name in ("audit_id", *reversed([name for name, _, _ in SUBMISSION_COLUMNS])):
            batch.drop_column(name)
