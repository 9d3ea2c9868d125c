"""The board's first schema (issue #34): accounts, packages, hidden seeds, secrets, submissions, jobs, rows.

Submissions were deduplicated on (package, entry, track, phase), whoever sent them.
The tables are written out here as they were, not taken from the code of today.
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

STATES = "state IN ('queued', 'running', 'done', 'failed')"


def upgrade() -> None:
    op.create_table(
        "accounts",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(100), nullable=False, unique=True),
        sa.Column("token_hash", sa.String(64), nullable=False, unique=True),
        sa.Column("admin", sa.Boolean, nullable=False),
        sa.Column("created", sa.Double, nullable=False),
    )
    op.create_table(
        "packages",
        sa.Column("sha256", sa.String(71), primary_key=True),
        sa.Column("bytes", sa.LargeBinary, nullable=False),
        sa.Column("size", sa.BigInteger, nullable=False),
        sa.Column("created", sa.Double, nullable=False),
    )
    op.create_table(
        "hidden_seeds",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("track", sa.String(100), nullable=False),
        sa.Column("track_hash", sa.String(64), nullable=False),
        sa.Column("version", sa.Integer, nullable=False),
        sa.Column("seeds", sa.Text, nullable=False),
        sa.Column("salt", sa.String(64), nullable=False),
        sa.Column("commitment", sa.String(71), nullable=False),
        sa.Column("created", sa.Double, nullable=False),
        sa.UniqueConstraint("track", "version"),
    )
    op.create_table(
        "secrets",
        sa.Column("name", sa.String(100), primary_key=True),
        sa.Column("value", sa.String(200), nullable=False),
    )
    op.create_table(
        "submissions",
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
        sa.CheckConstraint(STATES, name="state_known"),
        sa.UniqueConstraint("package_sha", "entry", "track", "phase", name="same_package_once"),
    )
    op.create_index("submissions_account", "submissions", ["account_id", "phase", "created"])
    op.create_table(
        "jobs",
        sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), primary_key=True),
        sa.Column("state", sa.String(8), nullable=False),
        sa.Column("lease_owner", sa.String(200), nullable=True),
        sa.Column("lease_until", sa.Double, nullable=True),
        sa.Column("fence", sa.BigInteger, nullable=False),
        sa.Column("heartbeat_at", sa.Double, nullable=True),
        sa.CheckConstraint(STATES, name="job_state_known"),
    )
    op.create_index("jobs_state", "jobs", ["state", "lease_until"])
    op.create_table(
        "rows",
        sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"), nullable=False),
        sa.Column("scenario", sa.String(100), nullable=False),
        sa.Column("seed_index", sa.Integer, nullable=False),
        sa.Column("seed", sa.BigInteger, nullable=False),
        *(sa.Column(c, sa.Double, nullable=False) for c in ("workforce_cost", "utilization", "downtime", "nsw")),
        *(sa.Column(c, sa.Integer, nullable=False) for c in ("episode_length", "invalid_actions")),
        *(sa.Column(c, sa.Double, nullable=True) for c in ("decision_ms_p50", "decision_ms_p99", "cpu_s")),
        sa.Column("machine", sa.Text, nullable=True),
        sa.Column("finished", sa.Double, nullable=False),
        sa.UniqueConstraint("submission_id", "scenario", "seed_index", name="one_row_per_unit"),
    )


def downgrade() -> None:
    for table in ("rows", "jobs", "submissions", "secrets", "hidden_seeds", "packages", "accounts"):
        op.drop_table(table)
