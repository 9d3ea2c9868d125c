"""The hosted board's routes, one ``APIRouter`` per area, as in the FastAPI full-stack template.

``submissions`` (upload, list, read, withdraw) and ``boards`` (tracks, rankings) answer
JSON under ``/api``; ``html`` serves the pages. ``deps`` holds the dependencies (the board,
the account), ``answers`` the response models, ``upload`` the streamed upload form.
:func:`wfbench.leaderboard.server.app.create_app` puts them together (docs/leaderboard.md).
"""
