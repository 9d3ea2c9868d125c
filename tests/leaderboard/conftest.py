import pytest


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    """A fresh hosted-board database: a SQLite file, or a PostgreSQL database of its own (``postgres_url``)."""
    if request.param == "sqlite":
        return str(tmp_path / "board.sqlite")
    return request.getfixturevalue("postgres_url")


@pytest.fixture
def open_board(db_url):
    """``open_board(tracks, **kwargs)``: a created :class:`Board` on ``db_url``, closed after the test."""
    from wfbench.leaderboard.board.db import Board

    made = []

    def open_(tracks, **kwargs):
        b = Board(db_url, tracks=tracks, **kwargs)
        b.create()
        made.append(b)
        return b

    yield open_
    for b in made:
        b.close()
