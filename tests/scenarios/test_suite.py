"""The suite registry: suite-v1's scenarios and split, its hash, the normalized score and its constants."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import wfbench
from wfbench.core.config import ScenarioConfig
from wfbench.harness.suite import compute_reference, evaluate_suite
from wfbench.scenarios import (
    DATA,
    SUITES,
    Suite,
    SuiteScenario,
    get_suite,
    normalize,
    reference,
    references,
)

TRAIN = ["small", "paper-64", "nonstationary", "table2-g32-f25-s10", "table2-g256-f25-s5", "surge-64",
         "clustered-64", "real-benelux"]
HELDOUT = ["large", "city", "table2-g128-f50-s25", "table2-g32-f100-s25", "slow-64", "churn-64", "novice-64",
           "real-nyc"]


def _mini(**changes) -> Suite:
    """A two-scenario suite of cheap presets, named suite-v1 so that it reads suite-v1's constants."""
    small = ScenarioConfig.preset("small")
    scenarios = (SuiteScenario("small-v1", "small", 1, "train", "tiny", small),
                 SuiteScenario("large-v1", "large", 1, "heldout", "large", ScenarioConfig.preset("large")))
    return dataclasses.replace(Suite("suite-v1", 1, scenarios, "two cheap scenarios"), **changes)


def test_suite_v1__has_the_sixteen_scenarios_and_split_the_lead_fixed():
    s = get_suite("suite-v1")
    assert s.ids("train") == [f"{p}-v1" for p in TRAIN]
    assert s.ids("heldout") == [f"{p}-v1" for p in HELDOUT]
    assert s.ids() == s.ids("train") + s.ids("heldout")
    assert all(sc.why and sc.version == 1 and sc.config.name == sc.preset for sc in s.scenarios)
    assert list(SUITES) == ["suite-v1"] and SUITES["suite-v1"] is s
    assert s.public_seeds == tuple(range(1000, 1050)) and s.test_seeds == tuple(range(50))


def test_suite_v1__every_scenario_has_reference_constants_for_its_current_definition():
    s = get_suite("suite-v1")
    data = references("suite-v1")
    assert data["seeds"] == list(range(50)) and data["wfbench_version"]  # which seeds and wfbench made them
    assert data["suite_hash"] == s.hash
    for sc in s.scenarios:
        entry = data["scenarios"][sc.id]
        assert entry["hash"] == sc.hash, f"{sc.id}: recompute with tools/suite_references.py"
        assert entry["random_ref"] < entry["bound_ref"] <= 1


def test_hash__changes_with_a_config_a_split_or_the_seeds():
    base = _mini()
    assert base.hash == _mini().hash and len(base.hash) == 16
    other_config = dataclasses.replace(base.scenarios[0], config=base.scenarios[0].config.replace(horizon=100))
    assert _mini(scenarios=(other_config, base.scenarios[1])).hash != base.hash
    other_split = dataclasses.replace(base.scenarios[1], split="train")
    assert other_split.hash != base.scenarios[1].hash
    assert _mini(scenarios=(base.scenarios[0], other_split)).hash != base.hash
    assert _mini(test_seeds=tuple(range(49))).hash != base.hash


def test_scenario__takes_an_id_or_an_unambiguous_preset_name():
    s = get_suite("suite-v1")
    assert s.scenario("paper-64").id == "paper-64-v1" == s.scenario("paper-64-v1").id
    twice = dataclasses.replace(s.scenarios[0], id="small-v2", version=2)
    with pytest.raises(ValueError, match="'small' is ambiguous in suite-v1: give one of small-v1, small-v2"):
        _mini(scenarios=(*_mini().scenarios, twice)).scenario("small")
    with pytest.raises(ValueError, match="unknown scenario 'nope' in suite-v1; allowed: small-v1, large-v1"):
        _mini().scenario("nope")


def test_bad_names__say_what_is_allowed():
    with pytest.raises(ValueError, match="unknown suite 'suite-v9'; allowed: suite-v1"):
        get_suite("suite-v9")
    with pytest.raises(ValueError, match="unknown split 'test'; allowed: train, heldout"):
        _mini().ids("test")
    with pytest.raises(ValueError, match="split 'dev' is not allowed; allowed: train, heldout"):
        SuiteScenario("x-v1", "small", 1, "dev", "", ScenarioConfig.preset("small"))
    with pytest.raises(ValueError, match="unknown scenario 'nope' in suite-v1; allowed: small-v1, paper-64-v1, "):
        normalize(0.5, "nope")


def test_normalize__random_reference_is_0_and_bound_reference_is_1():
    lo, hi = reference("small-v1")
    assert normalize(lo, "small-v1") == 0.0 and normalize(hi, "small") == 1.0
    x = normalize(np.array([lo, (lo + hi) / 2, hi]), "small-v1")
    np.testing.assert_allclose(x, [0.0, 0.5, 1.0])
    assert isinstance(normalize(0.5, "small-v1"), float)


@pytest.mark.parametrize("scenario", ["small-v1", "paper-64-v1", "table2-g32-f25-s10-v1"])
def test_reference_constants__recomputed_for_cheap_scenarios_match_the_committed_file(scenario):
    committed = json.loads((DATA / "suite-v1.json").read_text())["scenarios"][scenario]
    assert compute_reference(get_suite("suite-v1").scenario(scenario)) == committed


def test_normalize__refuses_constants_of_another_definition():
    changed = dataclasses.replace(_mini().scenarios[0], config=ScenarioConfig.preset("small").replace(horizon=100))
    with pytest.raises(ValueError, match="small-v1 were computed for another definition .* recompute them"):
        normalize(0.5, "small-v1", _mini(scenarios=(changed,)))


def test_evaluate_suite__one_row_per_scenario_and_seed_with_the_normalized_score():
    df = evaluate_suite("heuristic", _mini(), seeds=[0, 1])
    assert list(df.columns[:3]) == ["scenario", "split", "normalized"]
    assert list(df["scenario"]) == ["small-v1", "small-v1", "large-v1", "large-v1"]
    assert list(df["split"]) == ["train", "train", "heldout", "heldout"]
    assert list(df["seed"]) == [0, 1, 0, 1]
    alone = wfbench.evaluate("heuristic", "large", [0, 1])
    np.testing.assert_array_equal(df["nsw"].to_numpy()[2:], alone["nsw"].to_numpy())
    np.testing.assert_array_equal(df["normalized"].to_numpy()[2:], normalize(alone["nsw"].to_numpy(), "large-v1"))
    assert df.attrs["suite"] == "suite-v1" and df.attrs["policy"] == "heuristic"
    held = evaluate_suite("heuristic", _mini(), seeds=[0], split="heldout")
    assert list(held["scenario"]) == ["large-v1"]


def test_evaluate_suite__is_the_package_name():
    assert wfbench.evaluate_suite is evaluate_suite


# the command line


def _cli(capsys, *argv):
    from wfbench.cli import main

    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_suite_list_and_show__name_the_scenarios_split_hash_and_constants(capsys):
    status, out, _ = _cli(capsys, "suite", "list")
    s = get_suite("suite-v1")
    assert status == 0 and "suite-v1" in out and s.hash in out
    status, out, _ = _cli(capsys, "suite", "show", "suite-v1")
    assert status == 0 and f"hash {s.hash}" in out
    lo, hi = reference("real-nyc-v1")
    line = next(x for x in out.splitlines() if x.startswith("real-nyc-v1"))
    assert "heldout" in line and f"{lo:.4f}" in line and f"{hi:.4f}" in line and s.scenario("real-nyc").why in line
    status, out, _ = _cli(capsys, "suite", "show", "suite-v1", "--format", "json")
    data = json.loads(out)
    assert data["hash"] == s.hash and [x["id"] for x in data["scenarios"]] == s.ids()


@pytest.mark.parametrize(("argv", "message"), [
    (["suite", "show", "suite-v9"], "unknown suite 'suite-v9'; allowed: suite-v1"),
    (["evaluate", "--policy", "random", "--suite", "suite-v9"], "--suite: unknown suite 'suite-v9'; allowed: suite-v1"),
    (["evaluate", "--policy", "random", "--suite", "suite-v1", "--split", "test"],
     "--split: unknown split 'test'; allowed: train, heldout"),
    (["evaluate", "--policy", "random", "--suite", "suite-v1", "--scenario", "small"],
     "--scenario and --suite do not go together"),
    (["evaluate", "--policy", "random", "--split", "train"], "--split train applies to --suite only"),
    (["compare", "--policies", "random", "--suite", "suite-v1", "--split", "dev"],
     "--split: unknown split 'dev'; allowed: train, heldout"),
    (["compare", "--policies", "random", "--suite", "nope"], "--suite: unknown suite 'nope'; allowed: suite-v1"),
    (["compare", "--policies", "random", "--suite", "suite-v1", "--scenario", "paper-64"],
     "--scenario and --suite do not go together"),
])
def test_cli_bad_suite_input__one_line_naming_what_is_allowed(capsys, argv, message):
    status, out, err = _cli(capsys, *argv)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("wfbench: error: ") and message in err, err
    assert "Traceback" not in err


@pytest.mark.slow
def test_cli_evaluate_suite__a_row_per_scenario_then_the_aggregate_per_split(capsys):
    status, out, _ = _cli(capsys, "evaluate", "--policy", "heuristic", "--suite", "suite-v1", "--split", "train",
                          "--seeds", "2", "--backend", "serial", "--no-progress")
    assert status == 0
    ids = get_suite("suite-v1").ids("train")
    lines = out.splitlines()
    assert [x.split()[0] for x in lines[1:1 + len(ids)]] == ids
    df = evaluate_suite("heuristic", "suite-v1", [0, 1], scenarios=["small"])
    small = next(x for x in lines if x.startswith("small-v1"))
    assert f"{df['normalized'].mean():.3f}" in small.split()
    agg = next(x for x in lines if x.startswith("train ") and "heuristic" in x)
    assert "8 x 2" in agg and not any(x.startswith("heldout") for x in lines)
    status, out, _ = _cli(capsys, "evaluate", "--policy", "heuristic", "--suite", "suite-v1", "--split", "train",
                          "--seeds", "2", "--backend", "serial", "--no-progress", "--format", "json")
    data = json.loads(out)
    assert data["suite_hash"] == get_suite("suite-v1").hash and list(data["aggregate"]) == ["train"]
    assert data["scenarios"]["small-v1"]["normalized"] == pytest.approx(df["normalized"].mean())
    assert data["scenarios"]["small-v1"]["nsw"] == pytest.approx(df["nsw"].mean())


@pytest.mark.slow
def test_cli_compare_suite__paired_per_scenario_with_the_probability_of_improvement(capsys):
    status, out, err = _cli(capsys, "compare", "--policies", "heuristic", "--baseline", "random", "--suite",
                            "suite-v1", "--split", "train", "--seeds", "2", "--backend", "serial", "--no-progress",
                            "--format", "md", "--poi-reps", "20")
    assert status == 0 and "the baseline 'random' is not in --policies" in err
    rows = [x for x in out.splitlines() if x.startswith("| small-v1")]
    assert len(rows) == 2 and "(baseline)" in rows[0] and "| 2 |" in rows[1].replace(" ", " ")
    agg = next(x for x in out.splitlines() if x.startswith("| train") and "heuristic" in x)
    assert "1.00 [1.00, 1.00]" in agg
