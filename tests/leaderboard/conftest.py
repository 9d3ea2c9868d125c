import pytest


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    """A fresh hosted-board database: a SQLite file, or a PostgreSQL database of its own (``postgres_url``)."""
    if request.param == "sqlite":
        return str(tmp_path / "board.sqlite")
    return request.getfixturevalue("postgres_url")
