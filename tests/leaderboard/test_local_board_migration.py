"""The local board's files of earlier wfbench versions migrate with nothing lost (issue #54).

``tests/data/local_board/`` holds files made once by ``make.py`` there (its docstring says
how and at which commit): a board of revision ``0002`` with the local tables that
``create_all`` made outside Alembic, the schema-4 store it was imported from, and what
that wfbench showed of the board. This wfbench must open both and show the same.
"""

from __future__ import annotations

import json
import shutil
import sqlite3
from contextlib import closing
from pathlib import Path

import pytest
from alembic.script import ScriptDirectory
from wfbench.leaderboard.board import migrations
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.tracks import TRACKS

from tests.leaderboard.test_leaderboard import TINY
from wfbench.cli import main

DATA = Path(__file__).parents[1] / "data" / "local_board"
EXPECTED = json.loads((DATA / "expected.json").read_text())
# local_entries' columns -> their place in submissions; local_rows' columns keep their names in rows
ENTRY_MOVES = {"builtin": "builtin", "fingerprint": "fingerprint", "fingerprint_detail": "fingerprint_detail",
               "budget": "budget", "wfbench_version": "wfbench_version", "created_at": "created_at",
               "action": "audit_action", "note": "audit_note", "moved_at": "audit_at", "audit_id": "audit_id"}
ROW_KEY = ("submission_id", "scenario", "seed_index")
HEAD = ScriptDirectory.from_config(migrations.config()).get_current_head()


@pytest.fixture()
def tiny_on_cli(monkeypatch):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)


def _tables(path: Path) -> dict[str, list[dict]]:
    with closing(sqlite3.connect(path)) as c:
        c.row_factory = sqlite3.Row
        names = [r[0] for r in c.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        return {n: [dict(r) for r in c.execute(f"SELECT * FROM {n} ORDER BY rowid")] for n in names}


def _show(db: Path, fmt: str, capsys) -> dict[str, str]:
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--format", fmt]) == 0
    out = capsys.readouterr()
    return {"stdout": out.out, "stderr": out.err}


@pytest.mark.slow
def test_a_board_of_revision_0002_migrates_with_every_value_and_shows_the_same(tmp_path, tiny_on_cli, capsys):
    db = tmp_path / "lb.sqlite"
    shutil.copyfile(DATA / "pre_0003.sqlite", db)
    before = _tables(db)
    assert before["alembic_version"] == [{"version_num": "0002"}] and before["local_rows"]
    Store(db).close()  # opening it migrates it
    after = _tables(db)
    assert after["alembic_version"] == [{"version_num": HEAD}] and HEAD == "0003"
    assert "local_entries" not in after and "local_rows" not in after, "the local tables went into the board's"
    subs = {s["id"]: s for s in after["submissions"]}
    for e in before["local_entries"]:
        assert {new: subs[e["submission_id"]][new] for new in ENTRY_MOVES.values()} == \
            {new: e[old] for old, new in ENTRY_MOVES.items()}, e["submission_id"]
    rows = {tuple(r[k] for k in ROW_KEY): r for r in after["rows"]}
    for p in before["local_rows"]:
        assert {c: rows[tuple(p[k] for k in ROW_KEY)][c] for c in p} == p
    for name, old in before.items():  # every other value of every table as it was
        if name not in ("local_entries", "local_rows", "alembic_version"):
            assert [{c: r[c] for c in old[0]} for r in after[name]] == old if old else after[name] == [], name
    assert {name: _show(db, name, capsys) for name in ("table", "csv")} == \
        {name: EXPECTED[name] for name in ("table", "csv")}
    with Store(db, create=False) as store:
        assert store.audit().to_csv(index=False) == EXPECTED["audit"]


@pytest.mark.slow
def test_a_schema4_store_imports_to_the_board_that_wfbench_showed(tmp_path, tiny_on_cli, capsys):
    """The committed schema-4 file, imported today and with the same entry withdrawn, shows what the old board did."""
    db = tmp_path / "lb.sqlite"
    shutil.copyfile(DATA / "schema4.sqlite", db)
    with Store(db) as store:
        assert store.imported_from == db.with_name(db.name + ".schema4")
        store.withdraw(TINY.name, "half", "withdrawn once imported")
        audit = store.audit().to_csv(index=False).splitlines()
    assert (db.with_name(db.name + ".schema4")).read_bytes() == (DATA / "schema4.sqlite").read_bytes()
    assert {name: _show(db, name, capsys) for name in ("table", "csv")} == \
        {name: EXPECTED[name] for name in ("table", "csv")}
    expected = EXPECTED["audit"].splitlines()
    when = expected[-1].split(",")[8]  # the withdrawal's own time
    assert audit[:-2] == expected[:-2] and [a.replace(a.split(",")[8], when) for a in audit[-2:]] == expected[-2:]


def test_the_old_name_of_leaderboard_baselines_is_refused_in_one_line(capsys):
    assert main(["leaderboard", "seed"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: ") and "invalid choice: 'seed'" in err
    assert "baselines" in err, "the line names the command to use"
