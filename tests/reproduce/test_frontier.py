"""wfbench reproduce frontier: pieces read from a suite run and cut to the seeds, played when missing, the verdict."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import wfbench.reproduce.frontier as target
from wfbench.cli import main
from wfbench.harness.backends import Execution
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


def test_frontier__reads_stored_pieces_cut_to_the_seeds_and_plays_the_missing(run):
    suite_out, out, result, steps = run
    assert steps == ["small-v1: heuristic", "small-v1: random", "small-v1: solver"]
    assert not (out / "cache" / "heuristic").exists()  # read from the suite run, not played again
    played = pd.read_csv(out / "cache" / "solver" / "small-v1.csv")
    assert played["seed"].tolist() == [1, 2]
    table = pd.read_csv(out / "frontier.csv").set_index("policy")
    stored = pd.read_csv(suite_out / "cache" / "heuristic" / "small-v1.csv").set_index("seed").loc[[1, 2]]
    expected = normalize(stored["nsw"].to_numpy(), "small-v1")
    assert table.loc["heuristic", "iqm"] == pytest.approx(np.mean(expected))  # IQM of 2 runs is their mean
    assert table.loc["heuristic", "cpu_s_per_episode"] == pytest.approx(stored["cpu_s"].mean())
    assert table.loc["heuristic", "cpu_ms_per_step"] == pytest.approx(1e3 * stored["cpu_s"].sum()
                                                                      / stored["episode_length"].sum())
    assert set(table["family"]) == {"heuristic", "random", "solver"}
    names = {p.name for p in result.files}
    assert {"frontier.md", "frontier.csv", "frontier-verdict.csv", "frontier.png", "frontier.svg"} <= names
    assert all(p.stat().st_size > 0 for p in result.files)


def test_frontier__a_piece_of_other_seeds_or_another_hash_is_not_taken(tmp_path, run):
    suite_out = run[0]
    sc = get_suite("suite-v1").scenario("small")
    assert target.find_piece([suite_out], "heuristic", sc, [3, 0])["seed"].tolist() == [3, 0]
    assert target.find_piece([suite_out], "heuristic", sc, [0, 4]) is None  # seed 4 was never played
    meta = suite_out / "cache" / "heuristic" / "small-v1.json"
    copy = tmp_path / "cache" / "heuristic"
    copy.mkdir(parents=True)
    (copy / "small-v1.csv").write_text((suite_out / "cache" / "heuristic" / "small-v1.csv").read_text())
    (copy / "small-v1.json").write_text(meta.read_text().replace(sc.hash, "0" * 16))
    assert target.find_piece([tmp_path], "heuristic", sc, [0]) is None


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


@pytest.mark.parametrize(("argv", "message"), [
    (["suite", "--split", "train"], "--split applies to frontier only, not to suite"),
    (["suite", "--reuse", "x"], "--reuse applies to frontier only, not to suite"),
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
