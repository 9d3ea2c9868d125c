"""The HTML pages: the home page and its upload form, a track's board, a submission (:mod:`..pages` draws them)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, RedirectResponse
from wfbench.leaderboard.server import pages
from wfbench.leaderboard.server.api import upload
from wfbench.leaderboard.server.api.answers import submission_json
from wfbench.leaderboard.server.api.deps import (
    BaseDep,
    BoardDep,
    LimitDep,
    SubmissionDep,
    authenticate,
    check_phase,
    check_track,
)

router = APIRouter(tags=["pages"], default_response_class=HTMLResponse)


@router.get("/", response_class=HTMLResponse)
def home(board: BoardDep, base: BaseDep, limit: LimitDep) -> str:
    """The tracks, the upload form."""
    return pages.home_page(board, base, limit)


@router.post("/submit", status_code=303, response_class=RedirectResponse,
             openapi_extra={"requestBody": upload.form_schema(token=True)},
             responses={303: {"description": "to the new submission's page"}})
async def post_form(request: Request, board: BoardDep, limit: LimitDep) -> RedirectResponse:
    """The home page's upload form: the token is a form field; on success, the submission's page."""
    form = await upload.read_upload(request, limit)
    account = await run_in_threadpool(authenticate, board, form.fields.get("token", ""))
    sub, _ = await run_in_threadpool(upload.submit, board, account, form)
    return RedirectResponse(f"/submissions/{sub.id}", status_code=303)


@router.get("/board/{track}", response_class=HTMLResponse)
def board_page(track: str, board: BoardDep, phase: str = "dev") -> str:
    """A track's board for one phase."""
    return pages.board_page(board, check_track(board, track), check_phase(phase))


@router.get("/submissions/{sub_id}", response_class=HTMLResponse)
def submission_page(board: BoardDep, sub: SubmissionDep, base: BaseDep) -> str:
    """A submission's page (it refreshes itself until the state is final)."""
    return pages.submission_page(submission_json(board, sub, base))
