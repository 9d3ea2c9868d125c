"""The hosted leaderboard: a server that takes policy packages, workers that evaluate them in a sandbox.

- :mod:`~wfbench.leaderboard.hosted.db`: the database (SQLite or PostgreSQL) and :class:`~.db.Board`,
  its API: accounts, packages by hash, submissions with quotas, rows, hidden seeds, the
  board as the local reports read it.
- :mod:`~wfbench.leaderboard.hosted.queue`: the job queue: claims with a lease, heartbeats, fenced writes.
- :mod:`~wfbench.leaderboard.hosted.hidden`: the development and test phases, the hidden test
  seeds and their published commitment.
- :mod:`~wfbench.leaderboard.hosted.worker`: ``wfbench worker``, which runs the queue through the
  sandbox (:mod:`wfbench.harness.isolation.sandbox`).
- :mod:`~wfbench.leaderboard.hosted.server`, :mod:`~wfbench.leaderboard.hosted.client`: ``wfbench serve``
  and ``wfbench leaderboard upload``.

Nothing is imported here: the server's and the database's dependencies (the ``server``
extra) load only with the module that needs them.
"""
