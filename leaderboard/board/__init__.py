"""The board engine both leaderboards run on: the database, the job queue, the hidden seeds and the worker.

``db`` holds the database and :class:`~.db.Board`, its API (accounts, packages, submissions with
quotas, rows, hidden seeds); ``migrations`` its Alembic revisions; ``queue`` the job queue
(leases, heartbeats, fenced writes); ``hidden`` the development and test phases and the hidden
seeds' commitment; ``worker`` (``wfbench worker``, and the local board's in-process runs) runs
the queue; ``seed`` enters the built-ins (``wfbench serve seed``). The local board
(:mod:`wfbench.leaderboard.store`) is this board on a SQLite file; the hosted board's web
service is :mod:`wfbench.leaderboard.server`. ``docs/leaderboard.md``, "One board".
"""
