"""Tuning across worlds (wfbench tune --scenarios): the normalized objective, held-out refusals, resumes, files."""

import json

import pytest
from wfbench.policies import registry
from wfbench.policies.table import SINCE_V2

from wfbench import policies
from wfbench.cli import main
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.harness.suite import evaluate_suite
from wfbench.scenarios import get_suite, normalize
from wfbench.tune import OBJECTIVE_WORLDS, tune

TWO = "small,table2-g32-f25-s10"  # the two cheapest training worlds of suite-v1
TWO_IDS = ["small-v1", "table2-g32-f25-s10-v1"]
FEW = {"workforce.high": None, "workforce.cooldown": (2, 40)}


def _run(tmp_path, trials=3, scenarios=TWO, **kw):
    kw.setdefault("params", FEW)
    kw.setdefault("seeds", "public:2")
    return tune("heuristic", trials=trials, scenarios=scenarios, study_db=tmp_path / "study.db",
                execution=Execution(threads=1),
                out=kw.pop("out", tmp_path / "tuned.json"), **kw)


def _mean_normalized(policy, ids, seeds):
    """The mean over the worlds of each one's mean normalized score, as the suite computes it."""
    df = evaluate_suite(policy, seeds=seeds, scenarios=ids)
    per_world = df.groupby("scenario")["normalized"].mean()
    assert sorted(per_world.index) == sorted(ids)
    return float(per_world.mean()), per_world.to_dict()


def test_tune_worlds__the_file_s_score_is_the_mean_normalized_score_recomputed(tmp_path):
    r = _run(tmp_path)
    data = json.loads(r.path.read_text())
    assert data["scenario"] == TWO and data["objective"] == OBJECTIVE_WORLDS == "mean normalized score"
    assert data["worlds"] == TWO_IDS and data["seeds"] == [1000, 1001] and data["trials"] == 3
    assert "--scenarios" in data["command"] and r.study_name == f"heuristic@{TWO}"
    # the suite's own per-row normalization, by another path than the study's
    score, per_world = _mean_normalized(str(r.path), TWO_IDS, [1000, 1001])
    assert data["best_score"] == pytest.approx(score, abs=1e-12)
    assert data["world_scores"] == pytest.approx(per_world, abs=1e-12)
    # the first trial is the untuned policy: its score is the base's, and the best is never below it
    untuned, untuned_worlds = _mean_normalized("heuristic", TWO_IDS, [1000, 1001])
    assert r.untuned_score == data["untuned_score"] == pytest.approx(untuned, abs=1e-12)
    assert data["untuned_world_scores"] == pytest.approx(untuned_worlds, abs=1e-12)
    assert data["best_score"] >= data["untuned_score"]
    # a world's score is (NSW - random) / (bound - random) with the suite's constants
    nsw = evaluate(str(r.path), get_suite("suite-v1").scenario("small").config, [1000, 1001])["nsw"].mean()
    assert data["world_scores"]["small-v1"] == pytest.approx(normalize(nsw, "small-v1"), abs=1e-12)


def test_tune_worlds__a_suite_split_is_its_training_scenarios(tmp_path):
    r = _run(tmp_path, trials=1, scenarios="suite-v1:train", seeds="public:1", params=["workforce.high"])
    assert r.tuned.extra["worlds"] == get_suite("suite-v1").ids("train")
    assert r.tuned.scenario == "suite-v1:train" and r.tuned.trials == 1


@pytest.mark.parametrize("spec, message", [
    ("suite-v1:heldout", "the heldout split is never trained on; allowed: suite-v1:train"),
    ("small,large", "large-v1 is a held-out scenario of suite-v1 and is never trained on; allowed: its training "
                    "split, suite-v1:train"),
    ("slow-64", "slow-64-v1 is a held-out scenario"),
    ("table2-g64-f25-s5", "in no suite's training split, so it has no normalized score to tune on; allowed: "
                          "suite-v1:train"),
])
def test_cli_tune_worlds__a_held_out_or_unnormalized_world_is_refused_in_one_line(tmp_path, monkeypatch, capsys,
                                                                                   spec, message):
    monkeypatch.chdir(tmp_path)
    assert main(["tune", "heuristic", "--scenarios", spec, "--trials", "1", "--study-db", "s.db", "--out",
                 "o.json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: --scenarios: ") and message in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert list(tmp_path.iterdir()) == [], "a refused call must write nothing (no study, no file)"


@pytest.mark.parametrize("argv, message", [
    (["--scenarios", TWO, "--scenario", "small"], "--scenario and --scenarios do not go together"),
    (["--scenarios", TWO, "--seeds", "test"], "test seeds"),
    (["--scenarios", "small,"], "allowed: a comma-separated list"),
])
def test_cli_tune_worlds__other_mistakes_are_one_line(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert main(["tune", "heuristic", *argv, "--study-db", "s.db"]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_tune_worlds__a_study_refuses_other_worlds_or_one_scenario_under_its_name(tmp_path):
    _run(tmp_path, trials=1, study_name="s")
    with pytest.raises(ValueError, match=r"was made with another scenario, worlds .*--study-name"):
        _run(tmp_path, trials=2, scenarios="small", study_name="s")
    with pytest.raises(ValueError, match=r"was made with another scenario, objective"):
        tune("heuristic", "small", 2, seeds="public:2", params=FEW, study_db=tmp_path / "study.db", study_name="s")
    with pytest.raises(ValueError, match="another seeds"):
        _run(tmp_path, trials=2, seeds="public:3", study_name="s")
    r = _run(tmp_path, trials=2, study_name="s")  # the same call resumes
    assert r.new_trials == 1 and r.tuned.trials == 2


def test_tune_worlds__scenario_or_scenarios_not_both_nor_neither(tmp_path, capsys):
    with pytest.raises(ValueError, match="do not go together") as api:
        tune("heuristic", "small", 1, scenarios=TWO, study_db=tmp_path / "s.db")
    with pytest.raises(ValueError, match="not neither"):
        tune("heuristic", trials=1, study_db=tmp_path / "s.db")
    assert not (tmp_path / "s.db").exists()
    # the command refuses both with the function's words, naming its options
    assert main(["tune", "heuristic", "--scenario", "small", "--scenarios", TWO, "--study-db",
                 str(tmp_path / "s.db")]) == 2
    assert capsys.readouterr().err == f"wfbench: error: {str(api.value).replace('scenario', '--scenario', 2)}\n"
    assert not (tmp_path / "s.db").exists()


@pytest.mark.slow
@pytest.mark.parametrize("name, base", [("heuristic-tuned-train", "heuristic"), ("solver-tuned-train", "solver")])
def test_the_shipped_train_tuned_policies_score_what_their_file_claims(name, base):
    assert registry.entry(name).kind == "tuned" and name in policies.names() and name in registry.deployable_names()
    # added after the oracle's numbers were published: compared with it, not inside it (a candidate from v2 on)
    assert registry.entry(name).candidate_of == SINCE_V2 and name not in registry.oracle_candidates()
    p, b = policies.get(name), policies.get(base)
    t = p.tuned_from
    ids = get_suite("suite-v1").ids("train")
    assert p.compiled and t.base == base and t.name == name and t.scenario == "suite-v1:train"
    assert t.objective == "mean normalized score" and t.extra["worlds"] == ids
    assert t.seeds and set(t.seeds) <= set(range(1000, 1050)) and t.best_score > t.extra["untuned_score"]
    assert p.params() != b.params() and set(p.params()) == set(b.tunable)
    assert f"--name {name}" in t.command and "--scenarios suite-v1:train" in t.command
    score, per_world = _mean_normalized(name, ids, t.seeds)
    assert t.best_score == pytest.approx(score, abs=1e-12) and t.extra["world_scores"] == pytest.approx(per_world)
    assert registry.parts(name) == tuple(f"{x} (tuned)" for x in registry.parts(base))


def test_wfbench_policies_lists_the_train_tuned_ones(capsys):
    assert main(["policies"]) == 0
    out = capsys.readouterr().out
    assert "heuristic-tuned-train  policies/tuned/heuristic-suite-v1-train.json" in out
    assert "solver-tuned-train     policies/tuned/solver-suite-v1-train.json" in out
