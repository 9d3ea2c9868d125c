"""The hosted leaderboard's web service: the app, its routes and pages, and the upload client.

``app`` (``wfbench serve``) puts the routers of ``api`` together over a
:class:`~wfbench.leaderboard.board.db.Board`; ``pages`` renders the boards and forms;
``client`` is ``wfbench leaderboard upload``. Nothing is imported here: the ``server`` extra's
dependencies load only with the module that needs them. ``docs/leaderboard.md``, "The hosted
leaderboard".
"""
