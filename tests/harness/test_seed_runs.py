"""Learned methods over training seeds (issue #28): the members' specs, the median rule that picks the shipped
seed, the pooled aggregate and per-seed scores of reproduce suite, and the suite board's row over seeds.

The real members (ppo-general-seed0..4.pt) are trained elsewhere; here two members are copies of a small shipped
checkpoint in a temporary CHECKPOINT_DIR, the second with a perturbed bias so the two play differently.
"""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pandas as pd
import pytest
from wfbench.policies import registry
from wfbench.policies.table import Checkpoint

import wfbench.reproduce.suite as target
from wfbench.analysis.aggregate import median_seed, pool_seeds, score_matrix, seed_scores
from wfbench.cli import main
from wfbench.harness.backends import Execution

SOURCE = registry.CHECKPOINT_DIR / "ppo-joint-paper-64.pt"
FAST = {"reps": 200, "poi_reps": 20}

torch = pytest.importorskip("torch")


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory):
    """A checkpoint folder with two training seeds of ``ppo-general`` and its shipped pick, a copy of seed 1."""
    d = tmp_path_factory.mktemp("checkpoints")
    shutil.copy(SOURCE, d / "ppo-general-seed0.pt")
    ck = torch.load(SOURCE, map_location="cpu", weights_only=False)
    key = next(k for k in ck["model"] if k.endswith("bias"))
    ck["model"][key] = ck["model"][key] + 0.5
    torch.save(ck, d / "ppo-general-seed1.pt")
    shutil.copy(d / "ppo-general-seed1.pt", d / "ppo-general.pt")
    return d


@pytest.fixture()
def members(checkpoints, monkeypatch):
    monkeypatch.setattr(registry, "CHECKPOINT_DIR", checkpoints)
    # the registry's networks, their files looked for in the temporary folder: ppo-general's pick and two seeds are
    # there, hindsight-general's one seed and every other network's file are not
    table = dict(registry.TABLE)
    table["ppo-general"] = dataclasses.replace(registry.TABLE["ppo-general"], recipe=Checkpoint(
        "ppo-general.pt", seeds=("ppo-general-seed0.pt", "ppo-general-seed1.pt")), summary="a test pick")
    table["hindsight-general"] = dataclasses.replace(registry.TABLE["hindsight-general"], recipe=Checkpoint(
        "hindsight-general.pt", seeds=("hindsight-general-seed0.pt",)), summary="not there")
    monkeypatch.setattr(registry, "TABLE", table)
    return checkpoints


# the selection rule

def test_median_seed_is_the_middle_of_five_and_ties_go_to_the_lower_seed():
    scores = {f"m#seed{i}": v for i, v in enumerate([0.50, 0.10, 0.90, 0.30, 0.70])}
    assert median_seed(scores) == "m#seed0"  # sorted 0.1, 0.3, 0.5, 0.7, 0.9: the 3rd
    assert median_seed({"a": 0.2, "b": 0.2, "c": 0.2, "d": 0.1, "e": 0.9}) == "b"  # d, a, b, c, e
    assert median_seed({"a": 1.0, "b": 0.0, "c": 2.0, "d": 3.0}) == "a"  # even: the lower middle
    assert median_seed({"only": 0.4}) == "only"
    with pytest.raises(ValueError, match="not finite"):
        median_seed({"a": 0.1, "b": float("nan")})
    with pytest.raises(ValueError, match="no training seeds"):
        median_seed({})


# the registry

def test_members_are_named_by_seed_and_are_not_shipped_networks_or_oracle_candidates(members):
    assert registry.seed_members("ppo-general") == ["ppo-general#seed0", "ppo-general#seed1"]
    assert registry.seed_members("hindsight-general") == [] and registry.seed_members("heuristic") == []
    assert registry.learned_names() == ["ppo-general"]
    assert not any("#" in n for n in [*registry.names(), *registry.oracle_candidates()])
    assert registry.shipped_member("ppo-general") == "ppo-general#seed1"  # byte for byte the pick's file
    p = registry.get("ppo-general#seed1@greedy")
    assert p.name == "ppo-general#seed1@greedy"
    assert registry.member_file("ppo-general#seed0@greedy") == members / "ppo-general-seed0.pt"


@pytest.mark.parametrize(("spec", "message"), [
    ("ppo-general#seed7", "'ppo-general' has training seeds 0-1 (ppo-general#seed0 ... ppo-general#seed1); "
                          "present: ppo-general#seed0, ppo-general#seed1"),
    ("ppo-general#seedx", "has training seeds 0-1"),
    ("hindsight-general#seed0", "its checkpoint hindsight-general-seed0.pt is not in"),
    ("nope#seed0", "'nope' has no training seeds; methods with seeds: ppo-general, hindsight-general"),
])
def test_a_bad_member_is_a_value_error_naming_what_is_allowed(members, spec, message):
    with pytest.raises(ValueError, match="policy") as err:
        registry.get(spec)
    assert message in str(err.value)


def test_cli__a_bad_member_is_one_line_on_stderr(members, capsys, tmp_path):
    status = main(["reproduce", "suite", "--policies", "ppo-general#seed9", "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "'ppo-general' has training seeds 0-1" in err


def test_cli_policies_lists_the_training_seeds(members, capsys):
    assert main(["policies"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("ppo-general#seedK"))
    assert "ppo-general#seed0, ppo-general#seed1 (2 of 2 trained)" in line and "shipped pick is seed1" in line
    assert "hindsight-general#seedK" not in out  # none of its seeds is there


# the aggregate

def test_pooled_runs_make_a_members_x_seeds_by_scenarios_matrix():
    frames = {f"m#seed{k}": pd.DataFrame({"scenario": ["a", "a", "a", "b", "b", "b"], "split": "train",
                                          "seed": [0, 1, 2] * 2, "normalized": np.arange(6) + 10.0 * k})
              for k in range(4)}
    pooled = pool_seeds(frames)
    m, ids = score_matrix(pooled)
    assert m.shape == (4 * 3, 2) and ids == ["a", "b"]
    assert sorted(m[:, 0]) == sorted(v for k in range(4) for v in (10.0 * k, 10.0 * k + 1, 10.0 * k + 2))
    per = seed_scores(frames)
    assert per["member"].tolist() == list(frames)
    assert per.loc[1, "a"] == pytest.approx(11.0) and per.loc[1, "mean_train"] == pytest.approx(12.5)
    with pytest.raises(ValueError, match="no training seeds"):
        pool_seeds({})


# reproduce suite

@pytest.fixture()
def suite_run(members, tmp_path):
    result = target.suite(tmp_path, seeds=[0, 1], policies=("heuristic", "ppo-general"), scenarios=["small"],
                          execution=Execution(backend="serial"), **FAST)
    return tmp_path, result


@pytest.mark.slow
def test_reproduce_suite_pools_the_members_and_writes_their_scores(suite_run):
    out, result = suite_run
    assert target.size(policies=("heuristic", "ppo-general"), scenarios=["small"]) == 5  # 2 + 2 seeds + bound
    agg = pd.read_csv(out / "suite-aggregate.csv").set_index("policy")
    assert {"heuristic", "ppo-general", "ppo-general (2 seeds)"} == set(agg.index)
    pooled = agg.loc["ppo-general (2 seeds)"]
    assert (pooled["runs"], pooled["scenarios"]) == (2 * 2, 1)  # (members x eval seeds, scenarios)
    scores = pd.read_csv(out / "suite-scores.csv").set_index("policy")
    members = scores.loc[["ppo-general#seed0", "ppo-general#seed1"], "normalized"]
    assert members.iloc[0] != members.iloc[1], "the two members play differently"
    assert pooled["mean"] == pytest.approx(members.mean())
    assert scores.loc["ppo-general", "normalized"] == pytest.approx(members.iloc[1]), "the pick is seed 1's copy"
    per = pd.read_csv(out / "suite-per-seed.csv")
    assert per["member"].tolist() == ["ppo-general#seed0", "ppo-general#seed1"]
    assert per["method"].eq("ppo-general").all() and per["shipped"].tolist() == [False, True]
    assert per["small-v1"].tolist() == pytest.approx(members.tolist())
    assert "iqm_train" in per and "iqm_heldout" not in per  # small is a training scenario
    md = (out / "suite-per-seed.md").read_text()
    assert "ppo-general#seed1 (shipped pick)" in md and "**ppo-general (2 seeds)**" in md
    assert "ppo-general (shipped pick: seed1)" in (out / "suite-aggregate.md").read_text()
    checks = pd.read_csv(out / "suite-checks.csv").iloc[0]
    assert bool(checks["bound_holds"])
    assert "ppo-general#seed" not in (out / "suite-scores.md").read_text().splitlines()[2]  # the table's header


@pytest.mark.slow
def test_reproduce_suite_checks_every_member_against_the_bound(members, tmp_path, monkeypatch):
    real = target._run

    def above(policy, sc, seeds, *a):
        df, wall = real(policy, sc, seeds, *a)
        if policy == "ppo-general#seed0":
            df = df.assign(nsw=2.0)  # no policy can score this: the check must say so
        return df, wall

    monkeypatch.setattr(target, "_run", above)
    target.suite(tmp_path, seeds=[0], policies=("ppo-general",), scenarios=["small"],
                 execution=Execution(backend="serial"), **FAST)
    checks = pd.read_csv(tmp_path / "suite-checks.csv").iloc[0]
    assert not bool(checks["bound_holds"]) and json.loads(checks["above_bound"]) == {"ppo-general#seed0": 1}


# the suite board

@pytest.mark.slow
def test_the_board_ranks_a_method_over_its_seeds_and_shows_each_seed(members, tmp_path):
    from wfbench.leaderboard import report
    from wfbench.leaderboard.store import Store

    from tests.leaderboard.test_leaderboard_suite import TINY, _row

    store = Store(tmp_path / "lb.sqlite")

    def entry(name, policy, train, heldout):
        sub, _ = store.open_submission(TINY, name, policy, "me", "0", fingerprint=name,
                                       budget=json.dumps({"kind": "builtin"}))
        rows = [_row("small-v1", s, train + 0.01 * s) for s in TINY.test_seeds]
        rows += [_row("slow-64-v1", s, heldout + 0.01 * s) for s in TINY.test_seeds]
        store.add_results(sub, "0", rows)
        store.set_status(sub.id, "done")

    entry("heuristic", "heuristic", 0.60, 0.60)
    entry("gen-0", "ppo-general#seed0", 0.70, 0.90)
    entry("gen-1", "ppo-general#seed1", 0.70, 0.70)
    entry("ppo-general", "ppo-general", 0.70, 0.70)  # the pick, seed 1's copy
    r = report.ranking(store, TINY, reps=200)
    t = r.table.set_index("name")
    assert t.loc["ppo-general (2 seeds)", "rank"] == 1 and t.loc["heuristic", "rank"] == 2
    for name in ("gen-0", "gen-1", "ppo-general"):
        assert pd.isna(t.loc[name, "rank"]), f"{name} is ranked through the method's row"
    from wfbench.scenarios import normalize

    runs = np.concatenate([normalize([0.90, 0.91, 0.92], "slow-64-v1", TINY.suite),
                           normalize([0.70, 0.71, 0.72], "slow-64-v1", TINY.suite)])
    assert t.loc["ppo-general (2 seeds)", "mean_heldout"] == pytest.approx(runs.mean())  # 6 runs x 1 scenario
    lo, hi = t.loc["ppo-general (2 seeds)", ["iqm_heldout_low", "iqm_heldout_high"]]
    assert lo <= t.loc["ppo-general (2 seeds)", "iqm_heldout"] <= hi
    text = report.render(r, "md")
    assert "| 1 | ppo-general (2 seeds) | ppo-general over training seeds 0, 1 |" in text
    assert "| gen-0 |" not in text.split(report.SCENARIOS_TITLE)[0], "seeds are not entries to rank"
    assert "the shipped pick of ppo-general, ranked over its training seeds" in text
    seeds = text.split(report.SEEDS_TITLE)[1]
    assert "| ppo-general | gen-1 (shipped pick) |" in seeds and "ppo-general (2 seeds), pooled (#1)" in seeds
    assert f"{normalize([0.90, 0.91, 0.92], 'slow-64-v1', TINY.suite).mean():.3f}" in seeds  # seed 0's held-out
    page = report.render(r, "html")
    assert "<table id='seeds'>" in page and "<td>gen-1 (shipped pick)</td>" in page
