"""A suite run's pieces: cut to the seeds asked, extended by only the seeds they lack, and planned before playing."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from wfbench.harness.backends import Execution
from wfbench.reproduce import pieces
from wfbench.scenarios import get_suite
from wfbench.scenarios import pieces as stored

SMALL = get_suite("suite-v1").scenario("small")
TIMING = ("cpu_s", "wall_s", "decision_ms_p50", "decision_ms_p99", "decision_ms_max")  # measured, not computed


def _played(monkeypatch):
    """Record every (policy, seeds) :func:`pieces.play` is asked for, and play it."""
    calls, real = [], pieces.play
    monkeypatch.setattr(pieces, "play", lambda policy, sc, seeds, ex: (calls.append((policy, list(seeds))),
                                                                       real(policy, sc, seeds, ex))[1])
    return calls


def _results(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=[c for c in TIMING if c in df]).reset_index(drop=True)


def test_a_piece_with_fewer_seeds_is_extended_by_only_the_missing_ones(tmp_path, monkeypatch):
    calls = _played(monkeypatch)
    committed, out = tmp_path / "committed", tmp_path / "out"
    pieces.obtain([committed], committed, "heuristic-stochastic", SMALL, [0, 2], Execution())
    merged = pieces.obtain([out, committed], out, "heuristic-stochastic", SMALL, [3, 0, 1, 2], Execution())
    assert calls == [("heuristic-stochastic", [0, 2]), ("heuristic-stochastic", [3, 1])]
    assert merged["seed"].tolist() == [3, 0, 1, 2]  # in the order asked
    whole = pieces.obtain([tmp_path / "fresh"], tmp_path / "fresh", "heuristic-stochastic", SMALL, [3, 0, 1, 2],
                          Execution())
    pd.testing.assert_frame_equal(_results(merged), _results(whole))  # the same bits as one run of all four
    stored = pd.read_csv(pieces.piece_path(out, "heuristic-stochastic", SMALL))
    assert stored["seed"].tolist() == [0, 1, 2, 3]
    meta = json.loads(pieces.piece_path(out, "heuristic-stochastic", SMALL).with_suffix(".json").read_text())
    assert meta["seeds"] == [0, 1, 2, 3] and [p["seeds"] for p in meta["parts"]] == [[0, 2], [3, 1]]
    assert all(p["provenance"]["code_sha256"] for p in meta["parts"])
    assert pieces.provenance_of(meta, 1) == meta["parts"][1]["provenance"]
    assert pieces.find([out], "heuristic-stochastic", SMALL, [2, 3]) is not None  # the next run finds all of it
    calls.clear()
    pieces.obtain([out, committed], out, "heuristic-stochastic", SMALL, [1, 2], Execution())
    assert calls == []  # a subset of a stored piece is cut from it, not played


def test_a_run_of_other_seeds_extends_the_piece_and_loses_none_it_held(tmp_path, monkeypatch):
    """``--seeds 0-9`` then ``--seeds 10-19``: a piece of both, a part per run, each run's batch recorded."""
    calls = _played(monkeypatch)
    pieces.obtain([tmp_path], tmp_path, "heuristic", SMALL, [0, 1], Execution())
    later = pieces.obtain([tmp_path], tmp_path, "heuristic", SMALL, [3, 2], Execution())
    assert calls == [("heuristic", [0, 1]), ("heuristic", [3, 2])] and later["seed"].tolist() == [3, 2]
    played = json.loads(pieces.piece_path(tmp_path, "heuristic", SMALL).with_suffix(".json").read_text())
    assert later.attrs["wall_s"] == played["parts"][-1]["wall_s"]  # the wall of the seeds asked, not the piece's
    path = pieces.piece_path(tmp_path, "heuristic", SMALL)
    meta = json.loads(path.with_suffix(".json").read_text())
    assert pd.read_csv(path)["seed"].tolist() == [0, 1, 2, 3] and meta["seeds"] == [0, 1, 2, 3]
    assert [(p["seeds"], p["batches"]) for p in meta["parts"]] == [([0, 1], [[0, 1]]), ([3, 2], [[3, 2]])]
    whole = pieces.obtain([tmp_path / "fresh"], tmp_path / "fresh", "heuristic", SMALL, [0, 1, 2, 3], Execution())
    pd.testing.assert_frame_equal(_results(pd.read_csv(path)), _results(whole))


def test_a_piece_of_another_scenario_hash_is_played_again(tmp_path, monkeypatch):
    calls = _played(monkeypatch)
    pieces.obtain([tmp_path], tmp_path, "heuristic", SMALL, [0], Execution())
    meta = pieces.piece_path(tmp_path, "heuristic", SMALL).with_suffix(".json")
    meta.write_text(meta.read_text().replace(SMALL.hash, "0" * 16))
    pieces.obtain([tmp_path], tmp_path, "heuristic", SMALL, [0, 1], Execution())
    assert calls == [("heuristic", [0]), ("heuristic", [0, 1])]
    assert "parts" not in json.loads(meta.read_text())  # nothing of the other hash was kept


def test_the_plan_estimates_from_the_stored_cost_and_says_what_it_cannot(tmp_path):
    pieces.obtain([tmp_path], tmp_path, "heuristic", SMALL, [0, 1], Execution())
    paper = get_suite("suite-v1").scenario("paper-64")
    todo = pieces.plan([tmp_path], ["heuristic", "solver"], [SMALL, paper], [0, 1, 2, 3])
    per = pd.read_csv(pieces.piece_path(tmp_path, "heuristic", SMALL))["cpu_s"].mean()
    by = {(m.policy, m.scenario): m for m in todo}
    assert by["heuristic", "small-v1"].seeds == (2, 3) and by["heuristic", "small-v1"].cpu_s == pytest.approx(2 * per)
    # no piece of heuristic on paper-64: its cost on the other scenario is the estimate
    assert by["heuristic", "paper-64-v1"].cpu_s == pytest.approx(4 * per)
    assert by["solver", "small-v1"].cpu_s is None
    text = pieces.describe_plan(todo, workers=2)
    assert text.splitlines()[0].startswith("to play: 4 pieces, 14 episodes; about ")
    assert "(" in text.splitlines()[0] and "on 2 workers)" in text.splitlines()[0]
    assert "plus 2 pieces with no stored cost to estimate from" in text
    assert pieces.plan([tmp_path], ["heuristic"], [SMALL], [1]) == []
    assert pieces.describe_plan([]) == "every piece is stored: nothing to play"
    alone = pieces.plan([tmp_path], ["solver"], [SMALL], [0])
    assert pieces.describe_plan(alone).splitlines()[0] == (
        "to play: 1 pieces, 1 episodes; no stored piece of these policies to estimate their cost from")


def _cost_piece(folder, policy, scenario, cpu_s):
    """A stored piece of two seeds whose episodes each cost ``cpu_s`` CPU seconds."""
    df = pd.DataFrame({"seed": [0, 1], "cpu_s": [cpu_s, cpu_s]})
    pieces.store(pieces.piece_path(folder, policy, scenario), df, policy, scenario, [0, 1], 1.0)


def test_a_lookahead_without_a_piece_here_is_estimated_from_its_bases_cost_here(tmp_path):
    suite = get_suite("suite-v1")
    paper, large, city = (suite.scenario(x) for x in ("paper-64", "large", "city"))
    # the base costs 2x on large and 40x on city what it costs on paper-64; the rollout has pieces on the first two
    for sc, cost in ((paper, 1.0), (large, 2.0), (city, 40.0)):
        _cost_piece(tmp_path, "solver-tuned", sc, cost)
    _cost_piece(tmp_path, "rollout-solver-tuned", paper, 30.0)
    _cost_piece(tmp_path, "rollout-solver-tuned", large, 50.0)
    _cost_piece(tmp_path, "heuristic", paper, 0.5)
    todo = pieces.plan([tmp_path], ["rollout-solver-tuned", "heuristic"], [city], [0, 1, 2], others=suite.scenarios)
    by = {m.policy: m for m in todo}
    # scaled from the scenario where the base's cost is nearest city's (large), not from its own cost elsewhere
    assert by["rollout-solver-tuned"].cpu_s == pytest.approx(3 * 50.0 * 40.0 / 2.0)
    assert by["rollout-solver-tuned"].source == ("large-v1", "solver-tuned")
    # a policy that builds on nothing: its cost elsewhere as it is, and the plan says so
    assert by["heuristic"].cpu_s == pytest.approx(3 * 0.5) and by["heuristic"].source == ("paper-64-v1", None)
    text = pieces.describe_plan(todo)
    assert "rollout-solver-tuned on city-v1: 3 seeds, about 50 min (its cost on large-v1, scaled by " \
           "solver-tuned's cost there and here)" in text
    assert "heuristic on city-v1: 3 seeds, about 2 s (its cost on paper-64-v1, not scaled)" in text
    # without the other scenarios, nothing to estimate from
    alone = pieces.plan([tmp_path], ["rollout-solver-tuned"], [city], [0])
    assert alone[0].cpu_s is None and alone[0].source is None


def test_a_preset_is_estimated_from_its_siblings_cost_before_its_bases(tmp_path):
    suite = get_suite("suite-v1")
    paper, city = suite.scenario("paper-64"), suite.scenario("city")
    # on city the dense base costs 1,000x (the rollouts play its sparse twin there), its 10 ms sibling 10x
    _cost_piece(tmp_path, "solver-tuned", paper, 1.0)
    _cost_piece(tmp_path, "solver-tuned", city, 1000.0)
    _cost_piece(tmp_path, "rollout-solver-tuned", paper, 3.0)
    _cost_piece(tmp_path, "rollout-solver-tuned", city, 30.0)
    _cost_piece(tmp_path, "rollout-solver-tuned-100ms", paper, 20.0)
    _cost_piece(tmp_path, "oracle-rollout", paper, 6.0)
    todo = pieces.plan([tmp_path], ["rollout-solver-tuned-100ms", "oracle-rollout"], [city], [0],
                       others=suite.scenarios)
    assert todo[0].cpu_s == pytest.approx(20.0 * 10.0) and todo[0].source == ("paper-64-v1", "rollout-solver-tuned")
    # the hindsight rollout is no rollout preset, but it builds on the same base: scaled by the rollout too
    assert todo[1].cpu_s == pytest.approx(6.0 * 10.0) and todo[1].source == ("paper-64-v1", "rollout-solver-tuned")


def test_a_plan_reads_costs_from_other_runs_and_reuses_none_of_them(tmp_path):
    suite = get_suite("suite-v1")
    paper = suite.scenario("paper-64")
    committed, out = tmp_path / "committed", tmp_path / "out"
    _cost_piece(committed, "heuristic", paper, 4.0)
    todo = pieces.plan([out], ["heuristic"], [paper], [0, 1], others=suite.scenarios, costs=[committed])
    assert [(m.policy, m.seeds, m.cpu_s) for m in todo] == [("heuristic", (0, 1), pytest.approx(8.0))]
    assert pieces.plan([out], ["heuristic"], [paper], [0, 1], others=suite.scenarios)[0].cpu_s is None


def test_first_piece_is_the_first_folders_that_holds_every_seed_asked_with_its_bits(tmp_path):
    few, all_, empty = tmp_path / "few", tmp_path / "all", tmp_path / "empty"
    odd = 0.1 + 0.2  # a float the default CSV parser may not read back bit for bit
    for folder, seeds in ((few, [0]), (all_, [0, 1])):
        path = stored.piece_path(folder, "heuristic#seed0", "small-v1")  # stored path-safe: heuristic_seed0
        path.parent.mkdir(parents=True)
        pd.DataFrame({"seed": seeds, "nsw": [odd] * len(seeds), "where": folder.name}).to_csv(path, index=False)
    assert stored.first_piece([empty, few, all_], "heuristic#seed0", "small-v1")["where"].tolist() == ["few"]
    got = stored.first_piece([empty, few, all_], "heuristic#seed0", "small-v1", [1, 0])
    assert got.index.name == "seed" and got["where"].tolist() == ["all", "all"] and got.loc[1, "nsw"] == odd
    assert stored.first_piece([few, all_], "heuristic#seed0", "small-v1", [2]) is None
    assert stored.first_piece([few, all_], "heuristic", "small-v1") is None
