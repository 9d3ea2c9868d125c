"""An upload: the multipart form read as it streams in, cut off at the package limit, and its fields checked.

The body is counted while it arrives, so a chunked upload is refused at the limit rather
than stored first and measured after (docs/leaderboard.md, "The threat model").
"""

from __future__ import annotations

import re
from collections.abc import AsyncIterator
from dataclasses import dataclass

from fastapi import HTTPException, Request
from starlette.datastructures import UploadFile
from starlette.formparsers import MultiPartException, MultiPartParser
from wfbench.leaderboard.board.db import Account, Board, BoardError, QuotaExceeded, Submission
from wfbench.leaderboard.server.api.deps import check_phase

from wfbench.harness.isolation.package import PackageError, check_entry, inspect

FORM_OVERHEAD = 64 * 1024  # what the form's other fields and the multipart framing may add to the package's bytes
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9 ._+#@-]{0,63}$")
FIELDS = ("package", "track", "phase", "name", "entry", "token")


def form_schema(token: bool = False) -> dict:
    """The upload form as the OpenAPI document describes it (the routes read the stream themselves)."""
    fields = {"package": {"type": "string", "format": "binary", "description": "the policy package (zip)"},
              "track": {"type": "string"}, "phase": {"type": "string", "enum": ["dev", "test"]},
              "name": {"type": "string"}, "entry": {"type": "string", "description": "module:attribute"}}
    if token:
        fields["token"] = {"type": "string", "description": "the account's token"}
    schema = {"type": "object", "required": ["package", "track", *(["token"] if token else [])], "properties": fields}
    return {"required": True, "content": {"multipart/form-data": {"schema": schema}}}


class TooLarge(Exception):
    """The request body went past the limit while it was read."""


@dataclass(frozen=True)
class Upload:
    """A parsed upload form: the package's bytes and the text fields."""

    data: bytes
    fields: dict[str, str]


def one_line(text: object) -> str:
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
        raise HTTPException(400, f"the upload form cannot be read: {one_line(exc.message)}") from None
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
    check_phase(phase)
    name = fields.get("name") or None
    if name is not None and not NAME.match(name):
        raise HTTPException(400, f"name {name[:80]!r} is not allowed; allowed: 1-64 letters, digits, spaces and "
                                 "._+#@-, starting with a letter or digit")
    entry = fields.get("entry") or None
    if entry is not None:
        try:
            check_entry(entry)
        except PackageError as exc:
            raise HTTPException(400, one_line(exc)) from None
    return track, phase, name, entry


def submit(board: Board, account: Account, upload: Upload) -> tuple[Submission, bool]:
    """Check the fields and the package, store it and submit it: (submission, created); HTTPException 400/429 else."""
    track, phase, name, entry = _check_fields(board, upload.fields)
    try:
        manifest = inspect(upload.data)
    except PackageError as exc:
        raise HTTPException(400, f"the package is refused: {one_line(exc)}") from None
    entry = entry or manifest.entry
    try:
        sha = board.put_package(upload.data)
        return board.submit(account, track, phase, sha, entry, name or entry)
    except QuotaExceeded as exc:
        raise HTTPException(429, one_line(exc)) from None
    except BoardError as exc:
        raise HTTPException(400, one_line(exc)) from None
