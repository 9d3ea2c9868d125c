"""Alembic's environment for the hosted board: runs the revisions on the connection :mod:`.migrations` hands it.

Only online, inside the caller's transaction (:func:`wfbench.leaderboard.board.migrations.upgrade`).
"""

from alembic import context

if context.is_offline_mode():
    raise SystemExit("the board's migrations run only on a database connection; allowed: "
                     "wfbench.leaderboard.board.migrations.upgrade(engine)")
context.configure(connection=context.config.attributes["connection"],
                  target_metadata=context.config.attributes.get("metadata"),
                  render_as_batch=True)  # SQLite rebuilds a table to change its constraints
with context.begin_transaction():
    context.run_migrations()
