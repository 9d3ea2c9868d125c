"""``wfbench serve baselines`` (issue #34): the built-ins enter a hosted board once, as submissions of the admin account
'wfbench', run in the sandbox by a real worker, and fill the board's comparison with the heuristic."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pandas as pd
import pytest
from wfbench.leaderboard.board.db import BoardError
from wfbench.leaderboard.board.seed import ACCOUNT, ENTRY, seed
from wfbench.leaderboard.board.worker import run_worker
from wfbench.leaderboard.server import pages
from wfbench.leaderboard.store import ROW_COLUMNS
from wfbench.leaderboard.tracks import scenario_track
from wfbench.policies.registry import LINEUPS

from wfbench.cli import main
from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate

TINY = scenario_track(name="tiny", config=ScenarioConfig.preset("small").replace(name="tiny", horizon=20),
                      public_seeds=tuple(range(1000, 1004)), test_seeds=(0, 1, 2),
                      description="a tiny track for the tests",
                      references={"tiny": (0.0, 1.0)})  # no published constants: normalized = NSW
ORACLE_LEFT_OUT = "it reads the trace (a hindsight oracle); a sandboxed policy sees observations only"


@pytest.fixture
def board(open_board):
    return open_board({"tiny": TINY})


def test_seeding_enters_each_builtin_once_in_both_phases(board):
    first = seed(board)
    lineup = LINEUPS["leaderboard"]
    assert [(s.name, s.phase) for s in first] == [(n, p) for p in ("dev", "test") for n in lineup]
    assert {s.left_out for s in first if s.name == "oracle"} == {ORACLE_LEFT_OUT}
    entered = [s for s in first if not s.left_out]
    assert len(entered) == 2 * (len(lineup) - 1) and all(s.created and s.state == "queued" for s in entered)
    subs = board.submissions("tiny")
    assert {(s.name, s.phase) for s in subs} == {(s.name, s.phase) for s in entered}  # no test-phase quota
    assert {(s.account, s.entry) for s in subs} == {(ACCOUNT, ENTRY)}
    heuristic = next(s for s in subs if s.name == "heuristic")
    with zipfile.ZipFile(io.BytesIO(board.package(heuristic.package_sha))) as z:
        assert "NAME = 'heuristic'" in z.read("wfbench_builtin.py").decode()
    again = seed(board)  # the same packages: the submissions already made
    assert not any(s.created for s in again)
    assert [s.submission_id for s in again] == [s.submission_id for s in first]
    assert len(board.submissions("tiny")) == len(subs)


def test_seeding_refuses_a_user_named_wfbench(board):
    board.add_account(ACCOUNT)  # not an admin: whoever holds its token must not own the baselines
    with pytest.raises(BoardError, match="account 'wfbench' exists and is not an admin account"):
        seed(board, phases=("dev",), names=("heuristic",))
    assert board.submissions("tiny") == []


def test_the_cli_seeds_a_track_and_says_what_it_did(tmp_path, capsys):
    db = str(tmp_path / "board.sqlite")
    assert main(["serve", "baselines", "--db", db, "--tracks", "paper-64", "--phase", "dev"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "heuristic on paper-64 (dev): submission 2 queued"
    assert f"oracle on paper-64 (dev): left out: {ORACLE_LEFT_OUT}" in out
    assert out[-1] == f"9 new submissions of account 'wfbench'; start 'wfbench worker --server {db}' to evaluate them"
    assert main(["serve", "baselines", "--db", db, "--tracks", "paper-64", "--phase", "dev"]) == 0  # again
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "heuristic on paper-64 (dev): already there, submission 2 (queued)" and out[-1].startswith("0 new")
    assert main(["serve", "baselines", "--db", db, "--phase", "final"]) == 2
    assert "argument --phase: invalid choice: 'final' (choose from" in capsys.readouterr().err
    assert main(["serve", "seed", "--db", db]) == 2  # the old name went with issue #54 (docs/changes.md)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: ") and "invalid choice: 'seed'" in err
    assert "baselines" in err, "the line names the command to use"


@pytest.mark.slow
@pytest.mark.parametrize("db_url", ["sqlite"], indirect=True)
def test_a_worker_runs_the_seeded_builtins_in_the_sandbox_and_the_heuristic_column_fills(bwrap, board):
    seed(board, phases=("dev",), names=("heuristic", "random"))
    assert pages.board_ranking(board, "tiny", "dev").table["ranked"].sum() == 0
    assert run_worker(board.url, once=True, poll_s=0.1, tracks={"tiny": TINY}) == 0
    subs = {s.name: s for s in board.submissions("tiny", "dev")}
    assert {s.state for s in subs.values()} == {"done"}, [s.reason for s in subs.values()]
    rows = board.rows(subs["heuristic"].id).set_index("seed")[list(ROW_COLUMNS)]
    direct = evaluate("heuristic", TINY.config, list(TINY.public_seeds), execution=Execution(threads=1))
    direct = direct.set_index("seed")[list(ROW_COLUMNS)]
    pd.testing.assert_frame_equal(rows.sort_index(), direct.sort_index(), check_exact=True, check_dtype=False)
    table = pages.board_ranking(board, "tiny", "dev").table.set_index("name")
    assert table.loc["heuristic", "ranked"] and table.loc["random", "ranked"]
    assert np.isfinite(table.loc["random", ["diff", "diff_low", "diff_high"]].astype(float)).all()
    assert table.loc["random", "common_seeds"] == len(TINY.public_seeds)
