"""``wfbench leaderboard`` is a shell over the API: show, the tracks seed fills, the lines about a submission."""

from __future__ import annotations

import pytest
from wfbench.leaderboard import submit as submit_mod
from wfbench.leaderboard.report import FORMATS
from wfbench.leaderboard.store import Store, show
from wfbench.leaderboard.submit import describe, seed_tracks, submit
from wfbench.leaderboard.tracks import TRACKS, get_track

from tests.leaderboard.test_leaderboard import TINY, _fast
from wfbench.cli import main


@pytest.fixture()
def tiny(monkeypatch):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)  # reachable from the command line for these tests
    return TINY


@pytest.mark.slow
def test_show_is_what_the_command_prints(tiny, tmp_path, capsys):
    db = tmp_path / "lb.sqlite"
    for name in ("heuristic", "random"):
        submit(tiny, name, name, db=db, **_fast())
    for fmt in ("table", "md", "csv"):
        board = show(tiny.name, db, fmt)
        assert board.refused == [] and board.left_out == []
        assert main(["leaderboard", "show", "--track", tiny.name, "--db", str(db), "--format", fmt]) == 0
        out = capsys.readouterr().out
        assert out == board.text + ("" if board.text.endswith("\n") else "\n") and "heuristic" in out
    with pytest.raises(ValueError, match="is not allowed") as api:
        show(tiny, db, "pdf")
    assert main(["leaderboard", "show", "--track", tiny.name, "--db", str(db), "--format", "pdf"]) == 2
    assert capsys.readouterr().err == f"wfbench: error: --{api.value}\n"
    assert f"allowed: {', '.join(FORMATS)}" in str(api.value)
    assert not (tmp_path / "none.sqlite").exists()
    with pytest.raises(Exception, match="none.sqlite"):
        show(tiny, tmp_path / "none.sqlite")
    assert not (tmp_path / "none.sqlite").exists(), "showing never creates a store"


def test_baselines_fills_the_api_s_tracks(monkeypatch, capsys):
    seeded = []
    monkeypatch.setattr(submit_mod, "seed_builtins", lambda tr, **kw: seeded.append(tr.name) or [])
    assert main(["leaderboard", "baselines", "--no-progress"]) == 0
    assert seeded == [t.name for t in seed_tracks()] == [t.name for t in TRACKS.values()
                                                         if t.name != "suite-v1"]
    seeded.clear()  # a track that runs a whole suite: only when named
    assert main(["leaderboard", "baselines", "--track", "suite-v1", "--no-progress"]) == 0
    assert seeded == [t.name for t in seed_tracks("suite-v1")] == ["suite-v1"]
    assert seed_tracks(get_track("large")) == [get_track("large")]


@pytest.mark.slow
def test_submit_lines_are_the_api_s(tiny, tmp_path, monkeypatch, capsys):
    db = tmp_path / "lb.sqlite"
    outcomes = []
    real = submit_mod.submit
    monkeypatch.setattr(submit_mod, "submit", lambda *a, **kw: outcomes.append(real(*a, **{**kw, **_fast()}))
                        or outcomes[-1])
    base = ["leaderboard", "submit", "--track", tiny.name, "--db", str(db), "--no-progress"]
    assert main([*base, "--policy", "heuristic", "--name", "mine"]) == 0
    assert main([*base, "--policy", "random", "--name", "mine", "--replace"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [o.action for o in outcomes] == ["new", "replaced"]
    assert out == [describe(o, tiny, Store(db).path) for o in outcomes]
    assert out[1].endswith("; the entry it replaced is in the audit tables") and "4 seeds stored" in out[1]
    assert main([*base, "--policy", "tests.lb_policies:Raises", "--name", "broken"]) == 1
    err = capsys.readouterr().err
    assert outcomes[-1].status == "failed"
    line = describe(outcomes[-1], tiny, Store(db).path, "; --traceback prints the whole trace")
    assert err == f"wfbench: {line}\n" and "failed: policy 'tests.lb_policies:Raises'" in line
    assert "submit again to resume" in line
