"""``/api/tracks`` and ``/api/board/{track}``: the tracks a board has and a phase's ranking, as JSON."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from wfbench.leaderboard.server import pages
from wfbench.leaderboard.server.api.answers import BoardRanking, Problem, Tracks, board_json
from wfbench.leaderboard.server.api.deps import BoardDep, check_phase, check_track

router = APIRouter(prefix="/api", tags=["boards"])


@router.get("/tracks", response_model=Tracks)
def get_tracks(board: BoardDep) -> Any:
    """Every track of the board, with its seeds and the test phase's commitment."""
    return {"tracks": [pages.track_info(board, name) for name in board.tracks]}


@router.get("/board/{track}", response_model=BoardRanking,
            responses={400: {"model": Problem}, 404: {"model": Problem}})
def get_board(track: str, board: BoardDep, phase: str = "dev") -> Any:
    """The ranking of a track's phase (``dev`` or ``test``)."""
    return board_json(board, check_track(board, track), check_phase(phase))
