"""What the JSON API answers: one pydantic model per answer, and the functions that fill them from the board.

The models are what ``/api/openapi.json`` describes for every answer.

A test-phase submission never carries its per-seed rows or its log: :class:`SubmissionDetail`
leaves those fields unset, and the routes answer without unset fields.
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from typing import Any

from pydantic import BaseModel, Field
from wfbench.leaderboard.board.db import Board, BoardError, Submission
from wfbench.leaderboard.server import pages


class Problem(BaseModel):
    """Every refusal: one line saying what is wrong and what is allowed."""

    detail: str


class Created(BaseModel):
    """An upload's answer: the submission (``created`` false: the same one was already there)."""

    id: int
    state: str
    created: bool
    url: str


class SubmissionSummary(BaseModel):
    """A submission in a list: what it is and where it stands, without rows or log."""

    id: int
    track: str
    phase: str
    name: str
    account: str
    entry: str
    package: str = Field(description="the package's content hash, sha256:<hex>")
    state: str = Field(description="queued, running, done, failed or withdrawn")
    reason: str = Field(description="one line; in a running test phase only its kind, except to an admin")
    kind: str
    fault: str
    note: str
    attempts: int
    created: str
    updated: str
    withdrawn: str | None
    url: str


class Progress(BaseModel):
    done: int
    total: int | None = Field(description="null when its track or seed list is gone: it cannot run")


class SubmissionDetail(SubmissionSummary):
    """A submission; ``log`` and ``rows`` are there for the development phase only (its seeds are public)."""

    progress: Progress
    result: dict[str, Any] | None
    log: str | None = None
    rows: list[dict[str, Any]] | None = None


class Submissions(BaseModel):
    """An account's submissions, oldest first (withdrawn ones included)."""

    account: str
    submissions: list[SubmissionSummary]


class SeedCount(BaseModel):
    seeds: str
    count: int


class HiddenSeedList(BaseModel):
    hidden: bool
    count: int
    version: int
    commitment: str


class TrackInfo(BaseModel):
    """A track: its hash, the public seeds of the development phase, the test phase's hidden seeds' commitment."""

    name: str
    hash: str
    description: str
    scenarios: int
    dev: SeedCount
    test: HiddenSeedList


class Tracks(BaseModel):
    tracks: list[TrackInfo]


class BoardRanking(BaseModel):
    """A phase's ranking: one record per entry, as the local board's table has them."""

    track: str
    phase: str
    commitment: str | None = Field(description="the hidden seeds' commitment (test phase), else null")
    entries: list[dict[str, Any]]
    refused: list[str]


def clean(value: Any) -> Any:
    """``value`` with NaN and infinities as None, so it is valid JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    return value


def when(epoch: float) -> str:
    return datetime.fromtimestamp(epoch, UTC).isoformat(timespec="seconds")


def _total(board: Board, sub: Submission) -> int | None:
    """How many rows the submission will have (None when its track or seed list is gone: it cannot run)."""
    try:
        return len(board.units(sub))
    except BoardError:
        return None


def summary_json(board: Board, sub: Submission, base: str, admin: bool = False) -> dict[str, Any]:
    """A submission in a list (:class:`SubmissionSummary`).

    ``reason`` is :meth:`Board.shown_reason` (in a running test phase, the word only,
    unless ``admin``); ``kind`` is that word and ``fault`` whose failure it is.
    """
    return {"id": sub.id, "track": sub.track, "phase": sub.phase, "name": sub.name, "account": sub.account,
            "entry": sub.entry, "package": sub.package_sha, "state": sub.state,
            "reason": board.shown_reason(sub, admin), "kind": sub.kind, "fault": sub.fault, "note": sub.note,
            "attempts": sub.attempts, "created": when(sub.created), "updated": when(sub.updated),
            "withdrawn": when(sub.withdrawn) if sub.withdrawn is not None else None,
            "url": f"{base}/submissions/{sub.id}"}


def submission_json(board: Board, sub: Submission, base: str, admin: bool = False) -> dict[str, Any]:
    """A submission (:class:`SubmissionDetail`): the per-seed rows and the log for the development phase only.

    A test-phase submission's rows are counted (its progress) and never listed; :meth:`Board.rows`
    leaves their seed out in any case.
    """
    rows = board.rows(sub.id)
    out = {**summary_json(board, sub, base, admin), "progress": {"done": len(rows), "total": _total(board, sub)},
           "result": clean(sub.result) if sub.result else None}
    if sub.phase == "dev":  # public seeds: the log and every row may be shown
        out["log"] = sub.log or ""
        out["rows"] = clean(json.loads(rows.to_json(orient="records"))) if len(rows) else []
    return out


def board_json(board: Board, track: str, phase: str) -> dict[str, Any]:
    """The ranking of ``track``'s ``phase`` (:class:`BoardRanking`): one record per entry."""
    r = pages.board_ranking(board, track, phase)
    entries = json.loads(r.table.to_json(orient="records")) if len(r.table) else []
    published = board.hidden_commitment(track) if phase == "test" else None
    return {"track": track, "phase": phase, "commitment": published.commitment if published else None,
            "entries": clean(entries), "refused": list(r.refused)}
