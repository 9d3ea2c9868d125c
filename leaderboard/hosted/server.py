"""The web server of a hosted board (``wfbench serve``): the upload API, the boards and submissions, as JSON and HTML.

:func:`create_app` makes a FastAPI app over a :class:`wfbench.leaderboard.hosted.db.Board`;
``wfbench serve`` runs it under uvicorn. The server never runs a policy: it stores the
package and queues the submission, and ``wfbench worker`` evaluates it in the sandbox.

An upload (``POST /api/submissions``, multipart: ``package``, ``track``, ``phase``, and
optionally ``name`` and ``entry``) is answered, in this order:

- 401 without a valid ``Authorization: Bearer TOKEN`` (checked before the body is read);
- 413 when the body is larger than the package limit: a declared ``Content-Length`` is
  refused before anything is read, and the body is counted while it streams in, so a
  chunked upload is cut off at the limit rather than stored first and measured after;
- 400 with a one-line reason for a bad form or a package :func:`wfbench.harness.isolation.package.inspect`
  refuses (zip-slip, zip bomb, no manifest, ...), an unknown track or phase;
- 429 when the account is over its phase's quota (jobs at once, N a day);
- 201 with ``{id, state, url}`` for a new submission, 200 for the same package, entry,
  track and phase already submitted by the same account (it is not evaluated twice).

An owner lists their submissions with ``GET /api/submissions`` and withdraws one with
``DELETE /api/submissions/{id}`` (the same bearer token): it leaves the board and its
queued job is cancelled.

What a reader sees of a submission depends on its phase: a development-phase submission
shows its log and its per-seed rows (the seeds are public), a test-phase one only its
state, reason and aggregate; no answer or page carries a hidden seed or a per-seed row of
the test phase. While a track's test phase runs, a test-phase failure's reason is only its
word of :data:`~wfbench.leaderboard.hosted.db.FAILURE_KINDS` (the policy's own text could
carry what it saw), except to an admin account's token.

The routes are ``APIRouter`` modules of :mod:`wfbench.leaderboard.hosted.api`, with the board
and the account as dependencies and a pydantic model for every JSON answer. The database
calls are synchronous (SQLAlchemy); the handlers that stream a body are ``async`` and run
those calls in Starlette's thread pool, the others are plain functions, which FastAPI runs
there itself.
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from wfbench.leaderboard.hosted import pages
from wfbench.leaderboard.hosted.api import boards, html, submissions
from wfbench.leaderboard.hosted.db import Board

from wfbench.harness.isolation.package import MAX_PACKAGE_BYTES


def answer(request: Request, status: int, detail: str, headers: dict[str, str] | None = None):
    """JSON ``{"detail": ...}`` for the API, a small page saying the same for a browser."""
    if request.url.path.startswith("/api/"):
        return JSONResponse({"detail": detail}, status, headers=headers)
    return HTMLResponse(pages.error_page(status, detail), status, headers=headers)


async def one_line_error(request: Request, exc: StarletteHTTPException):
    return answer(request, exc.status_code, str(exc.detail), exc.headers)


async def one_line_invalid(request: Request, exc: RequestValidationError):
    first = exc.errors()[0]
    where = ".".join(str(p) for p in first.get("loc", ()) if p not in ("path", "query", "body"))
    return answer(request, 422, f"{where} {first.get('input')!r} is not allowed: {first.get('msg', 'invalid')}")


def create_app(board: Board, max_package_bytes: int = MAX_PACKAGE_BYTES) -> FastAPI:
    """The app of ``board``: the JSON API under ``/api`` and the HTML pages.

    Args:
        board: the database (created, with its tracks).
        max_package_bytes: the largest package accepted; a larger upload is answered 413
            while it is read.
    """
    app = FastAPI(title="wfbench leaderboard", docs_url="/api/docs", openapi_url="/api/openapi.json",
                  redoc_url=None)
    app.state.board = board
    app.state.max_package_bytes = max_package_bytes
    for name in board.tracks:  # each test phase's commitment is published before its first submission
        board.ensure_hidden_seeds(name)
    app.add_exception_handler(StarletteHTTPException, one_line_error)
    app.add_exception_handler(RequestValidationError, one_line_invalid)
    for router in (submissions.router, boards.router, html.router):
        app.include_router(router)
    return app
