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

The database calls are synchronous (SQLAlchemy); the handlers that stream a body are
``async`` and run those calls in Starlette's thread pool, the others are plain functions,
which FastAPI runs there itself.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import AsyncIterator
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from fastapi import FastAPI, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse
from starlette.datastructures import UploadFile
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.formparsers import MultiPartException, MultiPartParser
from wfbench.leaderboard.hosted import pages
from wfbench.leaderboard.hosted.db import Board, BoardError, NotFound, NotYours, QuotaExceeded, Submission
from wfbench.leaderboard.hosted.hidden import PHASES

from wfbench.harness.isolation.package import MAX_PACKAGE_BYTES, PackageError, check_entry, inspect

FORM_OVERHEAD = 64 * 1024  # what the form's other fields and the multipart framing may add to the package's bytes
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 ._+#@-]{0,63}$")
FIELDS = ("package", "track", "phase", "name", "entry", "token")


class TooLarge(Exception):
    """The request body went past the limit while it was read."""


@dataclass(frozen=True)
class Upload:
    """A parsed upload form: the package's bytes and the text fields."""

    data: bytes
    fields: dict[str, str]


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def too_large(limit: int) -> HTTPException:
    """The 413 answer; ``Connection: close`` so that uvicorn drops the connection instead of draining the rest."""
    return HTTPException(413, f"the upload is larger than the package limit of {limit / 2**20:g} MiB "
                              f"({limit} bytes); allowed: a package of at most that size",
                         headers={"Connection": "close"})


async def _capped(request: Request, limit: int) -> AsyncIterator[bytes]:
    """The request body in chunks, raising :class:`TooLarge` as soon as more than ``limit`` bytes came in."""
    seen = 0
    async for chunk in request.stream():
        seen += len(chunk)
        if seen > limit:
            raise TooLarge
        yield chunk


async def read_upload(request: Request, limit: int) -> Upload:
    """The multipart form of an upload, read with at most ``limit`` package bytes (HTTPException 413/400 else)."""
    body_limit = limit + FORM_OVERHEAD
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > body_limit:
        raise too_large(limit)
    if not request.headers.get("content-type", "").startswith("multipart/form-data"):
        raise HTTPException(400, "the upload is not a multipart/form-data form; allowed: a form with the fields "
                                 "package (the file), track, phase, and optionally name and entry")
    parser = MultiPartParser(request.headers, _capped(request, body_limit), max_files=1, max_fields=len(FIELDS))
    try:
        form = await parser.parse()
    except TooLarge:
        raise too_large(limit) from None
    except MultiPartException as exc:
        raise HTTPException(400, f"the upload form cannot be read: {_one_line(exc.message)}") from None
    try:
        unknown = sorted(k for k in form if k not in FIELDS)
        if unknown:
            raise HTTPException(400, f"unknown form field {unknown[0]!r}; allowed: {', '.join(FIELDS[:5])}")
        package = form.get("package")
        if not isinstance(package, UploadFile):
            raise HTTPException(400, "the upload has no 'package' file; allowed: a form with the fields package (the "
                                     "file), track, phase, and optionally name and entry")
        data = await package.read(limit + 1)
    finally:
        await form.close()  # the spooled file, on disk past 1 MiB
    if len(data) > limit:
        raise too_large(limit)
    return Upload(data, {k: v.strip() for k, v in form.items() if isinstance(v, str)})


def _check_fields(board: Board, fields: dict[str, str]) -> tuple[str, str, str | None, str | None]:
    """track, phase, name and entry of an upload form, each checked with a one-line reason (HTTPException 400)."""
    track, phase = fields.get("track", ""), fields.get("phase", "dev") or "dev"
    if track not in board.tracks:
        raise HTTPException(400, f"unknown track {track!r}; allowed: {', '.join(board.tracks)}")
    _phase(phase)
    name = fields.get("name") or None
    if name is not None and not NAME.match(name):
        raise HTTPException(400, f"name {name[:80]!r} is not allowed; allowed: 1-64 letters, digits, spaces and "
                                 "._+#@-, starting with a letter or digit")
    entry = fields.get("entry") or None
    if entry is not None:
        try:
            check_entry(entry)
        except PackageError as exc:
            raise HTTPException(400, _one_line(exc)) from None
    return track, phase, name, entry


def _bearer(request: Request) -> str:
    scheme, _, token = request.headers.get("authorization", "").partition(" ")
    return token.strip() if scheme.lower() == "bearer" else ""


def _authenticate(board: Board, token: str):
    """The account of ``token``; HTTPException 401 (with the WWW-Authenticate header) without one."""
    if not token:
        raise HTTPException(401, "no token: send the header 'Authorization: Bearer TOKEN' (an admin makes a token "
                                 "with 'wfbench serve account add NAME')", headers={"WWW-Authenticate": "Bearer"})
    account = board.account(token)
    if account is None:
        raise HTTPException(401, "the token is not valid; ask the board's admin for one",
                            headers={"WWW-Authenticate": "Bearer"})
    return account


def _submit(board: Board, account, upload: Upload):
    """Check the fields and the package, store it and submit it: (submission, created); HTTPException 400/429 else."""
    track, phase, name, entry = _check_fields(board, upload.fields)
    try:
        manifest = inspect(upload.data)
    except PackageError as exc:
        raise HTTPException(400, f"the package is refused: {_one_line(exc)}") from None
    entry = entry or manifest.entry
    try:
        sha = board.put_package(upload.data)
        return board.submit(account, track, phase, sha, entry, name or entry)
    except QuotaExceeded as exc:
        raise HTTPException(429, _one_line(exc)) from None
    except BoardError as exc:
        raise HTTPException(400, _one_line(exc)) from None


def _clean(value: Any) -> Any:
    """``value`` with NaN and infinities as None, so it is valid JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def _when(epoch: float) -> str:
    return datetime.fromtimestamp(epoch, UTC).isoformat(timespec="seconds")


def _total(board: Board, sub: Submission) -> int | None:
    """How many rows the submission will have (None when its track or seed list is gone: it cannot run)."""
    try:
        return len(board.units(sub))
    except BoardError:
        return None


def summary_json(board: Board, sub: Submission, base: str, admin: bool = False) -> dict[str, Any]:
    """A submission in a list (``GET /api/submissions``): what it is and where it stands, without rows or log.

    ``reason`` is :meth:`Board.shown_reason` (in a running test phase, the word only,
    unless ``admin``); ``kind`` is that word and ``fault`` whose failure it is.
    """
    return {"id": sub.id, "track": sub.track, "phase": sub.phase, "name": sub.name, "account": sub.account,
            "entry": sub.entry, "package": sub.package_sha, "state": sub.state,
            "reason": board.shown_reason(sub, admin), "kind": sub.kind, "fault": sub.fault, "note": sub.note,
            "attempts": sub.attempts, "created": _when(sub.created), "updated": _when(sub.updated),
            "withdrawn": _when(sub.withdrawn) if sub.withdrawn is not None else None,
            "url": f"{base}/submissions/{sub.id}"}


def submission_json(board: Board, sub: Submission, base: str, admin: bool = False) -> dict[str, Any]:
    """What ``GET /api/submissions/{id}`` answers: the per-seed rows and the log for the development phase only.

    A test-phase submission's rows are counted (its progress) and never listed; :meth:`Board.rows`
    leaves their seed out in any case. Its reason is the word only while the test phase
    runs (:func:`summary_json`).
    """
    rows = board.rows(sub.id)
    out = {**summary_json(board, sub, base, admin), "progress": {"done": len(rows), "total": _total(board, sub)},
           "result": _clean(sub.result) if sub.result else None}
    if sub.phase == "dev":  # public seeds: the log and every row may be shown
        out["log"] = sub.log or ""
        out["rows"] = _clean(json.loads(rows.to_json(orient="records"))) if len(rows) else []
    return out


def board_json(board: Board, track: str, phase: str) -> dict[str, Any]:
    """The ranking of ``track``'s ``phase`` as ``GET /api/board/{track}`` answers it: one record per entry."""
    r = pages.board_ranking(board, track, phase)
    entries = json.loads(r.table.to_json(orient="records")) if len(r.table) else []
    published = board.hidden_commitment(track) if phase == "test" else None
    return {"track": track, "phase": phase, "commitment": published.commitment if published else None,
            "entries": _clean(entries), "refused": list(r.refused)}


def _base(request: Request) -> str:
    return str(request.base_url).rstrip("/")


def _phase(phase: str) -> str:
    if phase not in PHASES:
        raise HTTPException(400, f"unknown phase {phase!r}; allowed: {', '.join(PHASES)}")
    return phase


def _track(board: Board, track: str) -> str:
    if track not in board.tracks:
        raise HTTPException(404, f"unknown track {track!r}; allowed: {', '.join(board.tracks)}")
    return track


def _get_submission(board: Board, sub_id: int):
    sub = board.submission(sub_id)
    if sub is None:
        raise HTTPException(404, f"no submission {sub_id}")
    return sub


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
    limit = max_package_bytes
    for name in board.tracks:  # each test phase's commitment is published before its first submission
        board.ensure_hidden_seeds(name)

    def answer(request: Request, status: int, detail: str, headers: dict[str, str] | None = None):
        """JSON ``{"detail": ...}`` for the API, a small page saying the same for a browser."""
        if request.url.path.startswith("/api/"):
            return JSONResponse({"detail": detail}, status, headers=headers)
        return HTMLResponse(pages.error_page(status, detail), status, headers=headers)

    @app.exception_handler(StarletteHTTPException)
    async def one_line_error(request: Request, exc: StarletteHTTPException):
        return answer(request, exc.status_code, str(exc.detail), exc.headers)

    @app.exception_handler(RequestValidationError)
    async def one_line_invalid(request: Request, exc: RequestValidationError):
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ()) if p not in ("path", "query", "body"))
        return answer(request, 422, f"{where} {first.get('input')!r} is not allowed: {first.get('msg', 'invalid')}")

    @app.post("/api/submissions", status_code=201)
    async def post_submission(request: Request):
        account = await run_in_threadpool(_authenticate, board, _bearer(request))
        upload = await read_upload(request, limit)
        sub, created = await run_in_threadpool(_submit, board, account, upload)
        body = {"id": sub.id, "state": sub.state, "created": created, "url": f"{_base(request)}/submissions/{sub.id}"}
        return JSONResponse(body, 201 if created else 200)

    @app.get("/api/submissions")
    def get_mine(request: Request):
        """The token's account's submissions, oldest first (withdrawn ones included)."""
        account = _authenticate(board, _bearer(request))
        return {"account": account.name, "submissions": [summary_json(board, s, _base(request), account.admin)
                                                         for s in board.account_submissions(account)]}

    @app.get("/api/submissions/{sub_id}")
    def get_submission(sub_id: int, request: Request):
        """A submission; an admin account's token sees a running test phase's whole failure reasons."""
        admin = bool(_bearer(request)) and _authenticate(board, _bearer(request)).admin
        return submission_json(board, _get_submission(board, sub_id), _base(request), admin)

    @app.delete("/api/submissions/{sub_id}")
    def delete_submission(sub_id: int, request: Request):
        """Withdraw the token's account's submission: off the board, its queued job cancelled (404, 403 else)."""
        account = _authenticate(board, _bearer(request))
        try:
            sub = board.withdraw(account, sub_id)
        except NotFound as exc:
            raise HTTPException(404, exc.reason) from None
        except NotYours as exc:
            raise HTTPException(403, exc.reason) from None
        return summary_json(board, sub, _base(request), account.admin)

    @app.get("/api/tracks")
    def get_tracks():
        return {"tracks": [pages.track_info(board, name) for name in board.tracks]}

    @app.get("/api/board/{track}")
    def get_board(track: str, phase: str = "dev"):
        return board_json(board, _track(board, track), _phase(phase))

    @app.get("/", response_class=HTMLResponse)
    def home(request: Request):
        return pages.home_page(board, _base(request), limit)

    @app.post("/submit")
    async def post_form(request: Request):
        """The upload form of the home page: the token is a form field; on success, the submission's page."""
        upload = await read_upload(request, limit)
        account = await run_in_threadpool(_authenticate, board, upload.fields.get("token", ""))
        sub, _ = await run_in_threadpool(_submit, board, account, upload)
        return RedirectResponse(f"/submissions/{sub.id}", status_code=303)

    @app.get("/board/{track}", response_class=HTMLResponse)
    def board_page(track: str, phase: str = "dev"):
        return pages.board_page(board, _track(board, track), _phase(phase))

    @app.get("/submissions/{sub_id}", response_class=HTMLResponse)
    def submission_page(sub_id: int, request: Request):
        sub = _get_submission(board, sub_id)
        return pages.submission_page(submission_json(board, sub, _base(request)))

    return app
