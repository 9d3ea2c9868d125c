"""The web server of a hosted board (``wfbench serve``): the app over a board's database.

:func:`create_app` wires the routers of :mod:`wfbench.leaderboard.server.api` over a
:class:`~wfbench.leaderboard.board.db.Board`. The server never runs a policy: it stores
the package and queues the submission, and ``wfbench worker`` evaluates it in the
sandbox. Every refusal is one line, ``{"detail": ...}`` for the API and a small page for
a browser. What each route answers, in which order an upload is refused, and what a
reader sees of a test-phase submission: docs/leaderboard.md, "The server's code and its
API document".
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from wfbench.leaderboard.board.db import Board
from wfbench.leaderboard.server import pages
from wfbench.leaderboard.server.api import boards, html, submissions

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
