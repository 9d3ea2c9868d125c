"""Make the committed local boards of ``tests/leaderboard/test_local_board_migration.py``, once.

Run from the repository root at commit ``MADE_AT`` (the last one before revision ``0003``, which moved the
local board's own tables into ``submissions`` and ``rows``)::

    .venv/bin/python tests/data/local_board/make.py

It writes, beside itself:

- ``schema4.sqlite``: a local store of schema 4 (the sqlite3 file of wfbench before issue #45), written by
  ``tests/leaderboard/test_schema4_import.py``'s ``write_schema4``: ranked, legacy, failed and running
  entries, an edited row, withdrawn and replaced entries in the audit tables;
- ``pre_0003.sqlite``: that store imported by the local board of ``MADE_AT`` (board revision ``0002`` with
  the tables ``local_entries`` and ``local_rows`` that ``create_all`` made outside Alembic), after which one
  more entry was withdrawn through it;
- ``expected.json``: what that wfbench showed of ``pre_0003.sqlite``: ``leaderboard show`` as a table and as
  CSV (stdout and stderr), and ``Store.audit()`` as CSV.

Both files are small and never change: a later wfbench must open them and show the same.
"""

from __future__ import annotations

import io
import json
import shutil
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
MADE_AT = "9714552"  # the split of leaderboard/hosted/ (issue #54), the last commit before revision 0003


def show(db: Path, fmt: str) -> dict[str, str]:
    from wfbench.cli import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        assert main(["leaderboard", "show", "--track", "tiny-test", "--db", str(db), "--format", fmt]) == 0
    return {"stdout": out.getvalue(), "stderr": err.getvalue()}


def main() -> None:
    sys.path.insert(0, str(ROOT))
    from wfbench.leaderboard.store import Store
    from wfbench.leaderboard.tracks import TRACKS

    from tests.leaderboard.test_leaderboard import TINY
    from tests.leaderboard.test_schema4_import import write_schema4

    TRACKS[TINY.name] = TINY
    schema4, board = HERE / "schema4.sqlite", HERE / "pre_0003.sqlite"
    for path in (schema4, board, HERE / "pre_0003.sqlite.schema4"):
        path.unlink(missing_ok=True)
    write_schema4(schema4)
    shutil.copyfile(schema4, board)
    with Store(board) as store:  # imports it: the local board of MADE_AT
        store.withdraw(TINY.name, "half", "withdrawn once imported")
    (HERE / "pre_0003.sqlite.schema4").unlink()
    with Store(board, create=False) as store:
        audit = store.audit().to_csv(index=False)
    expected = {"table": show(board, "table"), "csv": show(board, "csv"), "audit": audit}
    (HERE / "expected.json").write_text(json.dumps(expected, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
