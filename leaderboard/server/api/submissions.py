"""``/api/submissions``: upload a package, list the account's submissions, read one, withdraw one.

An upload is answered 401 without a valid token (checked before the body is read), 413
past the package limit, 400 for a bad form or package, 429 over the quota, 201 for a new
submission and 200 for the same one again (docs/leaderboard.md, "The hosted leaderboard").
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.concurrency import run_in_threadpool
from wfbench.leaderboard.board.db import NotFound, NotYours
from wfbench.leaderboard.server.api import upload
from wfbench.leaderboard.server.api.answers import (
    Created,
    Problem,
    SubmissionDetail,
    Submissions,
    SubmissionSummary,
    submission_json,
    summary_json,
)
from wfbench.leaderboard.server.api.deps import AccountDep, AdminDep, BaseDep, BoardDep, LimitDep, SubmissionDep

router = APIRouter(prefix="/api/submissions", tags=["submissions"],
                   responses={401: {"model": Problem, "description": "no token, or not a valid one"}})


@router.post("", status_code=201, response_model=Created, openapi_extra={"requestBody": upload.form_schema()},
             responses={200: {"model": Created, "description": "the same submission, already there"},
                        400: {"model": Problem}, 413: {"model": Problem}, 429: {"model": Problem}})
async def post_submission(request: Request, response: Response, board: BoardDep, account: AccountDep,
                          limit: LimitDep, base: BaseDep) -> Any:
    """Upload a package (multipart: ``package``, ``track``, ``phase``, optionally ``name`` and ``entry``)."""
    form = await upload.read_upload(request, limit)
    sub, created = await run_in_threadpool(upload.submit, board, account, form)
    if not created:
        response.status_code = 200
    return {"id": sub.id, "state": sub.state, "created": created, "url": f"{base}/submissions/{sub.id}"}


@router.get("", response_model=Submissions)
def get_mine(board: BoardDep, account: AccountDep, base: BaseDep) -> Any:
    """The token's account's submissions, oldest first (withdrawn ones included)."""
    return {"account": account.name,
            "submissions": [summary_json(board, s, base, account.admin) for s in board.account_submissions(account)]}


@router.get("/{sub_id}", response_model=SubmissionDetail, response_model_exclude_unset=True,
            responses={404: {"model": Problem}})
def get_submission(board: BoardDep, admin: AdminDep, sub: SubmissionDep, base: BaseDep) -> Any:
    """A submission; an admin account's token sees a running test phase's whole failure reasons."""
    return submission_json(board, sub, base, admin)


@router.delete("/{sub_id}", response_model=SubmissionSummary,
               responses={403: {"model": Problem}, 404: {"model": Problem}})
def delete_submission(sub_id: int, board: BoardDep, account: AccountDep, base: BaseDep) -> Any:
    """Withdraw the token's account's submission: off the board, its queued job cancelled (404, 403 else)."""
    try:
        sub = board.withdraw(account, sub_id)
    except NotFound as exc:
        raise HTTPException(404, exc.reason) from None
    except NotYours as exc:
        raise HTTPException(403, exc.reason) from None
    return summary_json(board, sub, base, account.admin)
