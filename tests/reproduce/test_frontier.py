"""wfbench reproduce frontier: pieces read from a suite run and cut to the seeds, played when missing, the verdict."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import wfbench.reproduce.frontier as target
from wfbench.cli import main
from wfbench.harness.backends import Execution
from wfbench.reproduce import pieces
from wfbench.reproduce import suite as suite_target
from wfbench.scenarios import get_suite, normalize

FAST = {"reps": 200, "poi_reps": 20}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A suite run of two policies on seeds 0-3 of small, then the frontier on seeds 1-2 of its train split."""
    suite_out = tmp_path_factory.mktemp("suite")
    suite_target.suite(suite_out, seeds=[0, 1, 2, 3], policies=("heuristic", "random"), scenarios=["small"],
                       execution=Execution(), **FAST)
    out = tmp_path_factory.mktemp("frontier")
    steps = []
    result = target.frontier(out, seeds=[1, 2], policies=["heuristic", "random", "solver"], scenarios=["small"],
                             split="train", reuse=[suite_out], execution=Execution(), progress=steps.append, **FAST)
    return suite_out, out, result, steps


@pytest.mark.slow
def test_frontier__reads_stored_pieces_cut_to_the_seeds_and_plays_the_missing(run):
    suite_out, out, result, steps = run
    assert steps == ["small-v1: heuristic", "small-v1: random", "small-v1: solver"]
    assert not (out / "cache" / "heuristic").exists()  # read from the suite run, not played again
    played = pd.read_csv(out / "cache" / "solver" / "small-v1.csv")
    assert played["seed"].tolist() == [1, 2]
    table = pd.read_csv(out / "frontier-train.csv").set_index("policy")
    stored = pd.read_csv(suite_out / "cache" / "heuristic" / "small-v1.csv").set_index("seed").loc[[1, 2]]
    expected = normalize(stored["nsw"].to_numpy(), "small-v1")
    assert table.loc["heuristic", "iqm"] == pytest.approx(np.mean(expected))  # IQM of 2 runs is their mean
    assert table.loc["heuristic", "cpu_s_per_episode"] == pytest.approx(stored["cpu_s"].mean())
    assert table.loc["heuristic", "cpu_ms_per_step"] == pytest.approx(1e3 * stored["cpu_s"].sum()
                                                                      / stored["episode_length"].sum())
    assert set(table["family"]) == {"heuristic", "random", "solver"}
    names = {p.name for p in result.files}
    assert {"frontier-train.md", "frontier-train.csv", "frontier-train-verdict.csv", "frontier-train-run.json",
            "frontier-train.png", "frontier-train.svg"} <= names  # the held-out split's files are frontier.*
    assert all(p.stat().st_size > 0 for p in result.files)


@pytest.mark.slow
def test_frontier__classes_writes_the_measured_costs_the_policy_table_reads(tmp_path, run, monkeypatch):
    from wfbench.policies import table

    suite_out, out, _, _ = run
    path = tmp_path / "budgets.json"
    result = target.frontier(out, seeds=[1, 2], policies=["heuristic", "random", "solver"], scenarios=["small"],
                             split="train", reuse=[suite_out], execution=Execution(), classes=path, **FAST)
    assert path in result.files
    data = json.loads(path.read_text())
    measured = pd.read_csv(out / "frontier-train.csv", float_precision="round_trip").set_index("policy")
    assert data["cpu_ms_per_step"] == measured["cpu_ms_per_step"].to_dict()  # the frontier's own bits
    assert data["measured_on"] == {"suite": "suite-v1", "split": "train", "scenarios": ["small-v1"],
                                   "seeds": "1..2 (2)"}
    monkeypatch.setattr(table, "BUDGETS_FILE", path)
    table.measured_costs.cache_clear()
    try:
        assert table.TABLE["solver"].budget == table.Budget.of(measured.loc["solver", "cpu_ms_per_step"])
        assert table.TABLE["solver-tuned"].budget is None  # not drawn: not measured
        assert table.TABLE["solver-tuned"].budget_class == "not measured"
    finally:
        table.measured_costs.cache_clear()


@pytest.mark.slow
def test_frontier__a_piece_of_other_seeds_or_another_hash_is_not_taken(tmp_path, run):
    suite_out = run[0]
    sc = get_suite("suite-v1").scenario("small")
    assert pieces.find([suite_out], "heuristic", sc, [3, 0])["seed"].tolist() == [3, 0]
    assert pieces.find([suite_out], "heuristic", sc, [0, 4]) is None  # seed 4 was never played
    meta = suite_out / "cache" / "heuristic" / "small-v1.json"
    copy = tmp_path / "cache" / "heuristic"
    copy.mkdir(parents=True)
    (copy / "small-v1.csv").write_text((suite_out / "cache" / "heuristic" / "small-v1.csv").read_text())
    (copy / "small-v1.json").write_text(meta.read_text().replace(sc.hash, "0" * 16))
    assert pieces.find([tmp_path], "heuristic", sc, [0]) is None


def _row(policy, side, iqm, low, high, cost):
    return {"policy": policy, "side": side, "iqm": iqm, "iqm_low": low, "iqm_high": high, "cpu_ms_per_step": cost}


def test_verdicts__the_best_of_each_side_within_each_budget():
    table = pd.DataFrame([_row("cheap-or", "OR", 0.50, 0.49, 0.51, 0.5), _row("net", "learned", 0.55, 0.54, 0.56, 0.8),
                          _row("lookahead", "OR", 0.555, 0.545, 0.565, 20.0),
                          _row("oracle", "reference", 0.9, 0.89, 0.91, 0.1)])
    v = {x["budget_ms"]: x for x in target.verdicts(table)}
    assert (v[1.0]["OR_policy"], v[1.0]["learned_policy"], v[1.0]["ahead"], v[1.0]["apart"]) == \
        ("cheap-or", "net", "learned", True)
    assert (v[10.0]["OR_policy"], v[10.0]["ahead"]) == ("cheap-or", "learned")
    assert (v[100.0]["OR_policy"], v[100.0]["ahead"], v[100.0]["apart"]) == ("lookahead", "OR", False)
    only = target.verdicts(table[table["side"] != "learned"], budgets=[1.0])[0]
    assert only["learned_policy"] is None and only["ahead"] == "OR" and only["apart"] is None


def test_the_oracle_line_names_where_a_policy_is_above_it():
    frames = {"oracle": pd.DataFrame({"scenario": ["a", "a", "b"], "nsw": [0.8, 0.6, 0.5]}),
              "mine": pd.DataFrame({"scenario": ["a", "a", "b"], "nsw": [0.7, 0.6, 0.6]})}
    assert target._oracle_line(frames) == "The oracle's mean NSW is below: mine on b (0.6000 > 0.5000)."
    frames["mine"]["nsw"] = 0.5
    assert target._oracle_line(frames).startswith("The oracle's mean NSW is at least every other policy's here on "
                                                  "each of the 2 scenarios")


def test_family__joins_each_kind_on_its_line():
    assert [target.family(p) for p in ("rollout-solver-tuned-1ms", "mpc-ma", "scalefree-general", "solver-tuned",
                                       "heuristic-tuned-train", "oracle", "search-scalefree-general-1ms")] == \
        ["rollout", "mpc", "network", "solver", "heuristic", "oracle", "search"]
    # the network's search is the learned side's, as the network is
    assert target.SIDES["search"] == target.SIDES["network"] == "learned"


@pytest.mark.slow
def test_frontier__without_options_it_draws_what_the_committed_frontier_was_drawn_from(tmp_path, run, monkeypatch):
    suite_out, out, _, _ = run
    settings = json.loads((out / "frontier-train-run.json").read_text())
    assert settings == {"suite": "suite-v1", "split": "train", "seeds": [1, 2], "scenarios": ["small-v1"],
                        "policies": ["heuristic", "random", "solver"]}
    checkout = tmp_path / "checkout"
    (checkout / target.COMMITTED).mkdir(parents=True)
    (checkout / target.COMMITTED / "frontier-train-run.json").write_text(json.dumps({**settings, "seeds": [0, 3]}))
    monkeypatch.setattr(target, "checkout_root", lambda: checkout)
    assert target.default_reuse() == tuple(checkout / r for r in target.DEFAULT_REUSE)
    again = tmp_path / "again"
    said = []
    target.frontier(again, split="train", policies=["heuristic", "random"], reuse=[suite_out],
                    execution=Execution(), announce=said.append, **FAST)
    assert pd.read_csv(again / "frontier-train.csv")["policy"].tolist() == ["heuristic", "random"]
    assert json.loads((again / "frontier-train-run.json").read_text())["seeds"] == [0, 3]  # the committed seeds
    assert said == ["every piece is stored: nothing to play"]  # seeds 0 and 3 are in the suite run's pieces


@pytest.mark.slow
def test_frontier__plan_only_says_what_it_would_play_and_plays_nothing(tmp_path, run, monkeypatch):
    suite_out = run[0]
    monkeypatch.setattr(pieces, "play", lambda *a: pytest.fail("the plan played a piece"))
    result = target.frontier(tmp_path, seeds=[0, 1, 2, 3, 4, 5], policies=["heuristic", "ppo-general"],
                             scenarios=["small"], split="train", reuse=[suite_out], execution=Execution(workers=2),
                             plan_only=True, **FAST)
    assert result.files == [] and not any(tmp_path.iterdir())
    lines = result.text.splitlines()
    per = pd.read_csv(suite_out / "cache" / "heuristic" / "small-v1.csv")["cpu_s"].mean()
    assert lines[0].startswith("to play: 2 pieces, 8 episodes; about ")  # heuristic: 4, 5; ppo-general: 0-5
    assert lines[0].endswith(", plus 1 pieces with no stored cost to estimate from")  # no piece of ppo-general
    assert f"heuristic on small-v1: 2 seeds, about {2 * per:.0f} s" in result.text
    assert "ppo-general on small-v1: 6 seeds, cost unknown" in result.text


def test_pareto__each_point_on_the_front_beats_every_cheaper_one():
    assert target.pareto([1.0, 2.0, 3.0, 0.5, 2.0], [0.5, 0.4, 0.6, 0.5, 0.55]) == [3, 4, 2]
    assert target.pareto([1.0], [0.1]) == [0]


@pytest.mark.slow
def test_frontier_cli__plan_prints_the_plan_and_writes_nothing(tmp_path, capsys, run):
    suite_out = run[0]
    status = main(["reproduce", "frontier", "--plan", "--split", "train", "--scenarios", "small", "--seeds", "0-5",
                   "--policies", "heuristic", "--reuse", str(suite_out), "--out", str(tmp_path / "o"),
                   "--no-progress"])
    out, err = capsys.readouterr()
    assert status == 0 and err == ""
    assert out.startswith("to play: 1 pieces, 2 episodes; about ") and "heuristic on small-v1: 2 seeds" in out
    assert not (tmp_path / "o" / "cache").exists()


@pytest.mark.parametrize(("argv", "message"), [
    (["gap", "--plan"], "--plan applies to suite and frontier only, not to gap"),
    (["suite", "--split", "train"], "--split applies to frontier only, not to suite"),
    (["gap", "--reuse", "x"], "--reuse applies to suite and frontier only, not to gap"),
    (["suite", "--classes", "x.json"], "--classes applies to frontier only, not to suite"),
    (["frontier", "--split", "train", "--classes", "x.json"],
     "--classes applies to the held-out split only (the verdict's), not to train"),
    (["frontier", "--scenarios", "small"], "--scenarios: scenario small-v1 is in the train split, not heldout"),
    (["frontier", "--no-networks"], "--no-networks applies to suite only, not to frontier"),
])
def test_frontier_cli__bad_options_get_one_line_and_nothing_runs(tmp_path, capsys, argv, message):
    status = main(["reproduce", *argv, "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith("wfbench: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "frontier.md").exists()


def test_frontier_cli__an_unknown_split_names_the_allowed_ones(tmp_path, capsys):
    assert main(["reproduce", "frontier", "--split", "sideways", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == ("wfbench: error: argument --split: invalid choice: 'sideways' "
                           "(choose from 'train', 'heldout')")
