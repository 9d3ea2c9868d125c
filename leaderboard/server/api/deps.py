"""The routes' dependencies: the board and its package limit, the bearer token and its account, checked names."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, HTTPException, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from wfbench.leaderboard.board.db import Account, Board, Submission
from wfbench.leaderboard.board.hidden import PHASES


def get_board(request: Request) -> Board:
    """The app's board (``create_app`` puts it in ``app.state``)."""
    return request.app.state.board


def get_limit(request: Request) -> int:
    """The largest package the app accepts, in bytes."""
    return request.app.state.max_package_bytes


def base_url(request: Request) -> str:
    """The server's own address, for the ``url`` of a submission."""
    return str(request.base_url).rstrip("/")


BoardDep = Annotated[Board, Depends(get_board)]
LimitDep = Annotated[int, Depends(get_limit)]
BaseDep = Annotated[str, Depends(base_url)]
_bearer = HTTPBearer(auto_error=False, description="an account's token ('wfbench serve account add NAME')")


def bearer_token(credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]) -> str:
    """The token of ``Authorization: Bearer TOKEN``, or "" without one."""
    return credentials.credentials.strip() if credentials else ""


TokenDep = Annotated[str, Depends(bearer_token)]


def authenticate(board: Board, token: str) -> Account:
    """The account of ``token``; HTTPException 401 (with the WWW-Authenticate header) without one."""
    if not token:
        raise HTTPException(401, "no token: send the header 'Authorization: Bearer TOKEN' (an admin makes a token "
                                 "with 'wfbench serve account add NAME')", headers={"WWW-Authenticate": "Bearer"})
    account = board.account(token)
    if account is None:
        raise HTTPException(401, "the token is not valid; ask the board's admin for one",
                            headers={"WWW-Authenticate": "Bearer"})
    return account


def get_account(board: BoardDep, token: TokenDep) -> Account:
    """The account of the request's bearer token (401 without a valid one)."""
    return authenticate(board, token)


def is_admin(board: BoardDep, token: TokenDep) -> bool:
    """Whether the request carries an admin account's token (no token: False; an invalid one: 401)."""
    return bool(token) and authenticate(board, token).admin


AccountDep = Annotated[Account, Depends(get_account)]
AdminDep = Annotated[bool, Depends(is_admin)]


def check_phase(phase: str) -> str:
    """``phase`` if it is one of :data:`~wfbench.leaderboard.board.hidden.PHASES`; HTTPException 400 else."""
    if phase not in PHASES:
        raise HTTPException(400, f"unknown phase {phase!r}; allowed: {', '.join(PHASES)}")
    return phase


def check_track(board: Board, track: str) -> str:
    """``track`` if the board has it; HTTPException 404 naming those it has else."""
    if track not in board.tracks:
        raise HTTPException(404, f"unknown track {track!r}; allowed: {', '.join(board.tracks)}")
    return track


def get_submission(board: BoardDep, sub_id: int) -> Submission:
    """The submission of the path's ``sub_id``; HTTPException 404 else."""
    sub = board.submission(sub_id)
    if sub is None:
        raise HTTPException(404, f"no submission {sub_id}")
    return sub


SubmissionDep = Annotated[Submission, Depends(get_submission)]
