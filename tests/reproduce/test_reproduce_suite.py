"""wfbench reproduce suite on a tiny subset: the files, the numbers, the checks, and resuming from the cache."""

from __future__ import annotations

import pandas as pd
import pytest

import wfbench
import wfbench.reproduce.suite as target
from wfbench.cli import main
from wfbench.harness.backends import Execution
from wfbench.scenarios import normalize

POLICIES = ("random", "heuristic", "oracle")
FAST = {"reps": 200, "poi_reps": 20}


@pytest.fixture(scope="module")
def first(tmp_path_factory):
    out = tmp_path_factory.mktemp("suite")
    steps = []
    result = target.suite(out, seeds=[0, 1], policies=POLICIES, scenarios=["small"], execution=Execution(),
                          progress=steps.append, **FAST)
    return out, result, steps


@pytest.mark.slow
def test_suite__writes_scores_aggregate_profiles_scaling_and_checks(first):
    out, result, steps = first
    assert steps == ["small-v1: random", "small-v1: heuristic", "small-v1: oracle", "small-v1: bound"]
    assert target.size(policies=POLICIES, scenarios=["small"]) == len(steps)
    names = {p.name for p in result.files}
    for stem in ("suite-scores", "suite-aggregate", "suite-checks"):
        assert {f"{stem}.md", f"{stem}.csv"} <= names
    assert {"suite-profile-train.csv", "suite-profile-train.svg", "suite-profile-train.png", "suite-scaling.csv",
            "suite-scaling.svg", "suite-scaling.png"} <= names
    assert "suite-profile-heldout.csv" not in names  # small is in the training split only
    assert all(p.exists() and p.stat().st_size > 0 for p in result.files)


@pytest.mark.slow
def test_suite__scores_are_the_evaluator_s_normalized(first):
    out, _, _ = first
    scores = pd.read_csv(out / "suite-scores.csv").set_index("policy")
    heuristic = wfbench.evaluate("heuristic", "small", [0, 1])["nsw"].to_numpy()
    assert scores.loc["heuristic", "nsw"] == pytest.approx(heuristic.mean(), abs=1e-12)
    assert scores.loc["heuristic", "normalized"] == pytest.approx(normalize(heuristic, "small-v1").mean(), abs=1e-12)
    from wfbench.core.bound import score_upper_bound

    bound = score_upper_bound(wfbench.scenario("small"), [0, 1])
    assert scores.loc["bound", "nsw"] == pytest.approx(bound.mean(), abs=1e-12)
    agg = pd.read_csv(out / "suite-aggregate.csv").set_index("policy")
    assert list(agg["split"].unique()) == ["train"]
    assert agg.loc["heuristic", "mean"] == pytest.approx(scores.loc["heuristic", "normalized"])
    assert agg.loc["oracle", "p_improve"] == 1.0  # the oracle beats the heuristic on both seeds
    scaling = pd.read_csv(out / "suite-scaling.csv")
    assert set(scaling["family"]) == {"random", "heuristic", "oracle"} and (scaling["env_steps_per_s"] > 0).all()


@pytest.mark.slow
def test_suite__checks_that_the_bound_holds_and_the_oracle_leads(first):
    out, result, _ = first
    checks = pd.read_csv(out / "suite-checks.csv").iloc[0]
    assert bool(checks["bound_holds"]) and bool(checks["oracle_at_least_deployable"])
    assert checks["best_deployable"] == "heuristic"
    assert "The bound holds: yes" in result.text
    assert "The oracle is at least every deployable policy on 1 of 1 scenarios" in result.text


@pytest.mark.slow
def test_suite__a_rerun_reads_the_cache_and_writes_the_same_files(first, monkeypatch):
    out, result, _ = first
    before = {p.name: p.read_bytes() for p in result.files if p.suffix in (".csv", ".md", ".svg")}

    def refuse(*args, **kwargs):
        raise AssertionError("a cached (policy, scenario) ran again")

    monkeypatch.setattr(target, "_run", refuse)
    again = target.suite(out, seeds=[0, 1], policies=POLICIES, scenarios=["small"], execution=Execution(), **FAST)
    after = {p.name: p.read_bytes() for p in again.files if p.suffix in (".csv", ".md", ".svg")}
    assert after.keys() == before.keys()
    for name in after:
        if name != "suite-scaling.csv" and name != "suite-scaling.svg":  # fresh wall times vs the cached ones
            assert after[name] == before[name], name


@pytest.mark.slow
def test_suite__a_stored_piece_is_cut_to_fewer_seeds_and_extended_by_only_the_missing_ones(first, monkeypatch):
    out, _, _ = first
    ran = []
    real = target._run
    monkeypatch.setattr(target, "_run", lambda policy, sc, seeds, *a: (ran.append((policy, list(seeds))),
                                                                       real(policy, sc, seeds, *a))[1])
    target.suite(out, seeds=[0], policies=("random",), scenarios=["small"], execution=Execution(), **FAST)
    assert ran == []
    target.suite(out, seeds=[0, 1, 2], policies=("random",), scenarios=["small"], execution=Execution(), **FAST)
    assert ran == [("random", [2]), ("bound", [2])]


@pytest.mark.slow
def test_suite__plan_only_says_what_is_missing_and_plays_nothing(first, monkeypatch):
    out, _, _ = first
    monkeypatch.setattr(target, "_run", lambda *a: pytest.fail("the plan played a piece"))
    said = []
    result = target.suite(out, seeds=[0, 1, 7], policies=("heuristic",), scenarios=["small"], execution=Execution(),
                          announce=said.append, plan_only=True, **FAST)
    assert result.files == [] and said == [result.text]
    assert result.text.startswith("to play: 2 pieces, 2 episodes")
    assert "heuristic on small-v1: 1 seeds" in result.text and "bound on small-v1: 1 seeds" in result.text


@pytest.mark.slow
def test_suite__reads_the_reused_runs_pieces_and_writes_only_to_its_own(first, tmp_path, monkeypatch):
    committed, _, _ = first
    before = sorted(p.name for p in (committed / "cache").rglob("*"))
    ran = []
    real = target._run
    monkeypatch.setattr(target, "_run", lambda policy, sc, seeds, *a: (ran.append((policy, list(seeds))),
                                                                       real(policy, sc, seeds, *a))[1])
    held = pd.read_csv(committed / "cache" / "heuristic" / "small-v1.csv")["seed"].tolist()  # 0, 1 and maybe more
    result = target.suite(tmp_path, seeds=[0, 1, 7], policies=("heuristic",), scenarios=["small"],
                          execution=Execution(), reuse=[committed], **FAST)
    assert 7 not in held and ran == [("heuristic", [7]), ("bound", [7])]  # the others came from the reused run
    assert sorted(p.name for p in (committed / "cache").rglob("*")) == before
    mine = pd.read_csv(tmp_path / "cache" / "heuristic" / "small-v1.csv")
    assert mine["seed"].tolist() == [0, 1, 7] and "heuristic" in result.text


def test_suite__without_members_plays_a_methods_shipped_pick_only(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(target, "_run", lambda *a: pytest.fail("the plan played a piece"))
    kw = {"seeds": [0], "policies": ("ppo-general",), "scenarios": ["small"], "execution": Execution(),
          "plan_only": True, **FAST}
    every = target.suite(tmp_path, **kw).text
    picks = target.suite(tmp_path, members=False, **kw).text
    assert "ppo-general#seed0 on small-v1" in every and "ppo-general on small-v1" in every
    assert "#seed" not in picks and "ppo-general on small-v1: 1 seeds" in picks
    assert picks.startswith("to play: 2 pieces")  # the pick and the bound
    assert target.size(policies=("ppo-general",), scenarios=["small"], members=False) == 2
    assert target.size(policies=("ppo-general",), scenarios=["small"]) > 2
    assert main(["reproduce", "suite", "--plan", "--no-members", "--no-progress", "--seeds", "0-0", "--policies",
                 "ppo-general", "--scenarios", "small", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("to play: 2 pieces") and "#seed" not in out


@pytest.mark.parametrize(("argv", "message"), [
    (["reproduce", "gap", "--policies", "random"], "--policies applies to suite, verify and frontier only, not to gap"),
    (["reproduce", "verify", "--no-networks"], "--no-networks applies to suite only, not to verify (give --policies)"),
    (["reproduce", "frontier", "--no-members"], "--no-members applies to suite only, not to frontier (give --"),
    (["reproduce", "table3", "--no-members"], "--no-members applies to suite only, not to table3"),
    (["reproduce", "suite", "--reuse", "/no/such/run"], "--reuse: /no/such/run holds no cache/ folder; allowed: "),
    (["reproduce", "suite", "--scenarios", "nope"], "--scenarios: unknown scenario 'nope' in suite-v1; allowed: "),
    (["reproduce", "suite", "--policies", "no-such-policy"], "no-such-policy"),
])
def test_cli_reproduce_suite__bad_options_in_one_line(capsys, tmp_path, argv, message):
    status = main([*argv, "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert status == 2 and err.count("\n") == 1 and message in err and "Traceback" not in err, err


@pytest.mark.slow
def test_suite__says_when_the_oracle_ran_with_no_deployable_beside_it(first, tmp_path):
    import shutil

    out, _, _ = first
    shutil.copytree(out / "cache", tmp_path / "cache")  # the oracle's piece is read, nothing played
    result = target.suite(tmp_path, seeds=[0, 1], policies=("oracle",), scenarios=["small"], execution=Execution(),
                          **FAST)
    assert "The oracle ran with no deployable candidate of it beside: nothing to compare." in result.text
    assert "The oracle was not run." not in result.text
