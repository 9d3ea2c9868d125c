"""The hosted leaderboard: a server that takes policy packages, workers that evaluate them in a sandbox.

``db`` holds the database and :class:`~.db.Board`, its API (accounts, packages, submissions with
quotas, rows, hidden seeds); ``queue`` the job queue (leases, heartbeats, fenced writes);
``hidden`` the development and test phases and the hidden seeds' commitment; ``worker``
(``wfbench worker``) runs the queue through the sandbox; ``server`` and ``client`` are ``wfbench
serve`` and ``wfbench leaderboard upload``. Nothing is imported here: the ``server`` extra's
dependencies load only with the module that needs them. ``docs/leaderboard.md``, "The hosted
leaderboard".
"""
