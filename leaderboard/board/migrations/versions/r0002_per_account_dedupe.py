"""Issue #42: dedupe per account; a failure's fault and kind, the worker time spent, the owner's withdrawal.

Adds ``board_meta`` (when each track's test phase ended) and classifies the failures
stored before: "lost its worker" is the board's fault, anything else the policy's, with
the kind its reason names (the rule as it was at this revision, written out here).
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

OLD_KEY, NEW_KEY = "same_package_once", "same_package_per_account"
KEY = ["package_sha", "entry", "track", "phase"]

# submissions as revision 0001 made it: SQLite rebuilds the table from this, not from a reflection
V1 = sa.MetaData()
V1_SUBMISSIONS = sa.Table(
    "submissions", V1,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("account_id", sa.Integer, sa.ForeignKey("accounts.id"), nullable=False),
    sa.Column("track", sa.String(100), nullable=False),
    sa.Column("track_hash", sa.String(64), nullable=False),
    sa.Column("phase", sa.String(8), nullable=False),
    sa.Column("package_sha", sa.String(71), sa.ForeignKey("packages.sha256"), nullable=False),
    sa.Column("entry", sa.String(300), nullable=False),
    sa.Column("name", sa.String(100), nullable=False),
    sa.Column("state", sa.String(8), nullable=False),
    sa.Column("reason", sa.Text, nullable=False),
    sa.Column("created", sa.Double, nullable=False),
    sa.Column("updated", sa.Double, nullable=False),
    sa.Column("attempts", sa.Integer, nullable=False),
    sa.Column("hidden_version", sa.Integer, nullable=True),
    sa.Column("log", sa.Text, nullable=False),
    sa.Column("result", sa.Text, nullable=True),
    sa.CheckConstraint("phase IN ('dev', 'test')", name="phase_known"),
    sa.CheckConstraint("state IN ('queued', 'running', 'done', 'failed')", name="state_known"),
    sa.UniqueConstraint(*KEY, name=OLD_KEY),
    sa.Index("submissions_account", "account_id", "phase", "created"),
)
sa.Table("accounts", V1, sa.Column("id", sa.Integer, primary_key=True))
sa.Table("packages", V1, sa.Column("sha256", sa.String(71), primary_key=True))


def kind_of_reason(reason: str) -> str:
    """The failure kind of a policy's reason, as the board told them apart at this revision."""
    text = reason.lower()
    if "took longer than" in text or "act timeout" in text or "time budget" in text or "cpu limit" in text:
        return "timed out"
    if "memoryerror" in text or "memory limit" in text or "out of memory" in text:
        return "out of memory"
    if "malformed action" in text:
        return "bad action"
    return "raised"


def upgrade() -> None:
    conn = op.get_bind()
    if not sa.inspect(conn).has_table("board_meta"):
        op.create_table(
            "board_meta",
            sa.Column("name", sa.String(100), primary_key=True),
            sa.Column("value", sa.String(200), nullable=False),
        )
    with op.batch_alter_table("submissions", copy_from=V1_SUBMISSIONS) as batch:
        batch.add_column(sa.Column("fault", sa.String(8), nullable=False, server_default=""))
        batch.add_column(sa.Column("kind", sa.String(20), nullable=False, server_default=""))
        batch.add_column(sa.Column("spent_s", sa.Double, nullable=False, server_default="0"))
        batch.add_column(sa.Column("withdrawn", sa.Double, nullable=True))
        batch.drop_constraint(OLD_KEY, type_="unique")
        batch.create_unique_constraint(NEW_KEY, ["account_id", *KEY])
    subs = sa.table("submissions", sa.column("id"), sa.column("reason"), sa.column("state"), sa.column("fault"),
                    sa.column("kind"))
    for sub_id, reason in conn.execute(sa.select(subs.c.id, subs.c.reason).where(subs.c.state == "failed")).all():
        board = str(reason).startswith("lost its worker")
        conn.execute(subs.update().where(subs.c.id == sub_id).values(
            fault="board" if board else "policy", kind="board fault" if board else kind_of_reason(str(reason))))


def downgrade() -> None:
    with op.batch_alter_table("submissions") as batch:
        batch.drop_constraint(NEW_KEY, type_="unique")
        batch.create_unique_constraint(OLD_KEY, KEY)
        for column in ("withdrawn", "spent_s", "kind", "fault"):
            batch.drop_column(column)
    op.drop_table("board_meta")
