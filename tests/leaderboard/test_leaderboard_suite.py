"""The suite-v1 track: a submission runs every scenario of the suite, one row per (scenario, seed); the board
ranks by the IQM of the normalized score over the held-out scenarios (issue #27)."""

from __future__ import annotations

import json

import pytest
from wfbench.leaderboard import report
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.submit import submit
from wfbench.leaderboard.tracks import TRACKS, Track, get_track

from wfbench.cli import main
from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution
from wfbench.scenarios import Suite, get_suite, normalize

FULL = get_suite("suite-v1")
# two real scenarios of suite-v1, one per split, on three seeds: their normalization constants are the suite's
TINY = Track(name="tiny-suite", suite=Suite(name="suite-v1", version=1, description="a subset for the tests",
                                                 scenarios=(FULL.scenario("small-v1"), FULL.scenario("slow-64-v1")),
                                                 test_seeds=(0, 1, 2)),
                  description="small-v1 (training) and slow-64-v1 (held out) on seeds 0-2")
SERIAL = Execution(backend="serial")


@pytest.fixture()
def db(tmp_path):
    return tmp_path / "lb.sqlite"


def _row(scenario, seed, nsw):
    return {"seed": seed, "scenario": scenario, "workforce_cost": 10.0, "utilization": 0.5, "downtime": 0.1,
            "nsw": nsw, "episode_length": 10, "invalid_actions": 0, "decision_ms_p50": 0.01, "decision_ms_p99": 0.02,
            "cpu_s": 0.01, "machine": "test machine"}


def _entry(store, name, nsw_train, nsw_heldout):
    sub, _ = store.open_submission(TINY, name, "heuristic", "me", "0", fingerprint=name,
                                   budget=json.dumps({"kind": "builtin"}))
    rows = [_row("small-v1", s, nsw_train + 0.01 * s) for s in TINY.test_seeds]
    rows += [_row("slow-64-v1", s, nsw_heldout + 0.01 * s) for s in TINY.test_seeds]
    store.add_results(sub, "0", rows)
    store.set_status(sub.id, "done")


def test_the_suite_track_is_listed_and_hashed_with_the_suite(capsys):
    tr = get_track("suite-v1")
    assert tr.suite is FULL and not tr.seeded and tr.hash == FULL.hash and tr.rank_split == "heldout"
    assert len(tr.units()) == 16 * 50 and tr.units()[0] == ("small-v1", 0)
    assert tr.configs()["city-v1"] == FULL.scenario("city-v1").config
    assert main(["leaderboard", "tracks"]) == 0
    assert f"suite-v1       hash {FULL.hash}" in capsys.readouterr().out


@pytest.mark.slow
def test_ranked_by_the_held_out_aggregate_not_by_the_mean_score(db):
    store = Store(db)
    _entry(store, "good-at-training", nsw_train=0.85, nsw_heldout=0.50)  # the higher mean NSW over all rows
    _entry(store, "good-held-out", nsw_train=0.45, nsw_heldout=0.80)
    r = report.ranking(store, TINY, baseline="good-at-training")
    t = r.table.set_index("name")
    assert t.loc["good-at-training", "nsw"] > t.loc["good-held-out", "nsw"]
    assert t["rank"].to_dict() == {"good-held-out": 1, "good-at-training": 2}
    held = normalize([0.80, 0.81, 0.82], "slow-64-v1", TINY.suite)
    assert t.loc["good-held-out", "iqm_heldout"] == pytest.approx(held.mean())  # IQM of 3 runs x 1 scenario
    for name in t.index:
        for split in ("heldout", "train"):
            assert t.loc[name, f"iqm_{split}_low"] <= t.loc[name, f"iqm_{split}"] <= t.loc[name, f"iqm_{split}_high"]
    assert t.loc["good-at-training", "iqm_train"] > t.loc["good-held-out", "iqm_train"], "training shown too"
    assert t.loc["good-held-out", "p_improve_heldout"] == 1.0
    again = report.ranking(store, TINY, baseline="good-at-training").table
    assert again.equals(r.table), "the intervals are seeded: the same rows give the same digits"
    text = report.render(r, "md")
    assert "| 1 | good-held-out | heuristic |" in text and report.SCENARIOS_TITLE in text
    assert "| slow-64-v1 | heldout |" in text


@pytest.mark.slow
def test_submit_runs_every_scenario_and_resumes_and_the_html_shows_the_track(db, monkeypatch, capsys):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)
    for policy in ("random", "heuristic"):
        out = submit(TINY, policy, policy, db=db, execution=SERIAL.replace(chunk_size=3))
        assert (out.status, out.stored_rows, out.new_rows) == ("complete", 6, 6), out.reason
    assert submit(TINY, "heuristic", "heuristic", db=db, execution=SERIAL).new_rows == 0, "complete: nothing to run"
    rows, refused = Store(db).results(TINY)
    assert refused == [] and len(rows) == 12
    assert set(zip(rows["scenario"], rows["seed"], strict=True)) == set(TINY.units())
    assert rows[["decision_ms_p50", "cpu_s"]].notna().all().all()
    t = report.ranking(Store(db), TINY).table.set_index("name")
    assert t.loc["heuristic", "rank"] == 1 and t.loc["random", "rank"] == 2
    assert t.loc["heuristic", "iqm_heldout"] > t.loc["random", "iqm_heldout"]
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db)]) == 0
    shown = capsys.readouterr().out
    assert "IQM, held out [95% CI]" in shown and "IQM, training [95% CI]" in shown and "6/6" in shown
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--format", "html"]) == 0
    page = capsys.readouterr().out
    assert "<title>wfbench leaderboard: tiny-suite</title>" in page and "<th>IQM, held out [95% CI]</th>" in page
    assert "<table id='scenarios'>" in page and "data:image/png;base64," in page
    assert "<td>slow-64-v1</td><td>heldout</td>" in page


def test_results_of_another_suite_version_are_refused(db):
    store = Store(db)
    _entry(store, "old", 0.6, 0.6)
    changed = Track(name=TINY.name, description=TINY.description,
                         suite=Suite(name="suite-v1", version=1, description="seeds changed",
                                     scenarios=TINY.suite.scenarios, test_seeds=(0, 1, 2, 3)))
    assert changed.hash != TINY.hash
    rows, refused = store.results(changed)
    assert rows.empty and len(refused) == 6
    assert refused[0] == (f"result of 'old', scenario slow-64-v1, seed 0: made on another version of track "
                          f"tiny-suite (hash {TINY.hash}, current {changed.hash}); refused")
    r = report.ranking(store, changed)
    assert r.table.loc[0, "rank"] is None and "0/8" in report.render(r, "table")


def test_time_left_weighs_scenarios_by_their_measured_and_estimated_cost(monkeypatch):
    """Issue #35: a count of episodes says little when one scenario costs a hundred of another."""
    from wfbench.leaderboard import submit as submit_mod

    now = [100.0]
    monkeypatch.setattr(submit_mod.time, "monotonic", lambda: now[0])
    small, big = ScenarioConfig.preset("small").replace(horizon=100), ScenarioConfig.preset("large")
    configs = {"a": small, "b": big}
    units = [(sc, s) for sc in configs for s in range(4)]
    clock = submit_mod.RemainingTime(units, configs, done={("a", 0)})
    assert clock.seconds_left() is None and clock.cost("b") is None  # nothing measured: no guess
    now[0] = 110.0  # 10 s for two episodes of "a" at 1 CPU second each
    clock.add([{"scenario": "a", "cpu_s": 1.0}, {"scenario": "a", "cpu_s": 1.0}])
    ratio = clock.size["b"] / clock.size["a"]
    assert clock.cost("a") == 1.0 and clock.cost("b") == pytest.approx(ratio)  # "b" by its size
    # left: one "a" and four "b" episodes; the pace: 10 wall seconds for 2 units of cost
    assert clock.seconds_left() == pytest.approx(10.0 * (1 + 4 * ratio) / 2)
    now[0] = 130.0
    clock.add([{"scenario": "b", "cpu_s": 50.0}])  # measured: "b" is what it costs, not what its size says
    assert clock.cost("b") == 50.0
    assert clock.seconds_left() == pytest.approx(30.0 * (1 * 1.0 + 3 * 50.0) / (2 * 1.0 + 1 * 50.0))
    clock.add([{"scenario": "b", "cpu_s": float("nan")}])  # a row without a measurement counts, adds no cost
    assert clock.left["b"] == 2 and clock.cost("b") == 50.0
    assert clock.per_scenario() == {"a": 2.0, "b": 50.0}


@pytest.mark.slow
def test_a_suite_submission_reports_its_time_per_scenario(db, monkeypatch, capsys):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)
    assert main(["leaderboard", "submit", "--policy", "heuristic", "--name", "h", "--track", TINY.name,
                 "--db", str(db), "--backend", "serial"]) == 0
    out, err = capsys.readouterr()
    line = next(x for x in out.splitlines() if x.startswith("CPU seconds per scenario"))
    assert "small-v1" in line and "slow-64-v1" in line, line
    # the bar: no estimate before the first rows, then one weighted by the scenarios' costs
    assert "0/6 episodes" in err and "time left: after the first episodes" in err and "time left: about" in err, err
    o = submit(TINY, "random", "r", db=db, execution=SERIAL)
    assert set(o.scenario_seconds) == {"small-v1", "slow-64-v1"} and all(t > 0 for t in o.scenario_seconds.values())


def test_a_one_scenario_track_is_a_suite_of_one_ranked_by_the_same_rule(db):
    from rliable import metrics

    from wfbench.analysis.stats import bootstrap_ci

    paper, large = get_track("paper-64"), get_track("large")
    assert paper.scenarios() == [("", FULL.scenario("paper-64-v1"))] and paper.hash == "c99646c6fa5c75b7"
    assert (paper.rank_split, large.rank_split, get_track("suite-v1").rank_split) == ("all", "heldout", "heldout")
    short = paper.with_seeds((0, 1, 2, 3), "paper-64 on four seeds")
    store = Store(db)
    nsw = {"low": [0.70, 0.71, 0.72, 0.90], "high": [0.75, 0.76, 0.77, 0.60]}
    for name, values in nsw.items():
        sub, _ = store.open_submission(short, name, "heuristic", "me", "0", fingerprint=name)
        store.add_results(sub, "0", [_row("", s, v) for s, v in zip(short.test_seeds, values, strict=True)])
        store.set_status(sub.id, "done")
    r = report.ranking(store, short, baseline="low", reps=200)
    t = r.table.set_index("name")
    for name, values in nsw.items():  # the rank key: the IQM of the normalized score with suite-v1's constants
        iqm = metrics.aggregate_iqm(normalize(values, "paper-64-v1", FULL).reshape(-1, 1))
        assert t.loc[name, "iqm_all"] == pytest.approx(iqm)
    # "low" has the higher mean NSW (0.7575 > 0.72) but the lower IQM: the IQM ranks
    assert t.loc["high", "rank"] == 1 and t.loc["low", "rank"] == 2 and t.loc["low", "nsw"] > t.loc["high", "nsw"]
    text = report.render(r, "table")
    assert "IQM, all scenarios [95% CI]" in text and "P(improvement over low), all scenarios" in text
    ci = bootstrap_ci(nsw["high"])  # the per-scenario table keeps the mean NSW with its interval
    line = next(ln for ln in text.splitlines() if ln.startswith("paper-64-v1") and " high " in ln)
    assert f"[{ci.low:.3f}, {ci.high:.3f}]" in line and "-0.0375 [" in line and " train " in line


def test_a_scenario_without_constants_is_shown_and_not_ranked(db):
    from wfbench.leaderboard.tracks import scenario_track

    own = scenario_track("own", ScenarioConfig.preset("small").replace(name="own", horizon=20), (100,), (0, 1),
                         "a scenario of no suite")
    store = Store(db)
    sub, _ = store.open_submission(own, "mine", "heuristic", "me", "0", fingerprint="mine")
    store.add_results(sub, "0", [_row("", s, 0.7) for s in own.test_seeds])
    store.set_status(sub.id, "done")
    r = report.ranking(store, own, reps=200)
    assert r.table.loc[0, "rank"] is None and r.table.loc[0, "nsw"] == pytest.approx(0.7)
    assert r.refused == ["scenario own: suite 'own' has no reference constants (own.json); compute them with "
                         "tools/suite_references.py; its rows are shown, not ranked"]
