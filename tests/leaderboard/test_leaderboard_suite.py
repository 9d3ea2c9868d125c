"""The suite-v1 track: a submission runs every scenario of the suite, one row per (scenario, seed); the board
ranks by the IQM of the normalized score over the held-out scenarios (issue #27)."""

from __future__ import annotations

import json

import pytest
from wfbench.leaderboard import suite_report
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.submit import submit
from wfbench.leaderboard.tracks import TRACKS, SuiteTrack, get_track

from wfbench.cli import main
from wfbench.scenarios import Suite, get_suite, normalize

FULL = get_suite("suite-v1")
# two real scenarios of suite-v1, one per split, on three seeds: their normalization constants are the suite's
TINY = SuiteTrack(name="tiny-suite", suite=Suite(name="suite-v1", version=1, description="a subset for the tests",
                                                 scenarios=(FULL.scenario("small-v1"), FULL.scenario("slow-64-v1")),
                                                 test_seeds=(0, 1, 2)),
                  description="small-v1 (training) and slow-64-v1 (held out) on seeds 0-2")


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
    store.set_status(sub.id, "complete")


def test_the_suite_track_is_listed_and_hashed_with_the_suite(capsys):
    tr = get_track("suite-v1")
    assert isinstance(tr, SuiteTrack) and tr.hash == FULL.hash
    assert len(tr.units()) == 16 * 50 and tr.units()[0] == ("small-v1", 0)
    assert tr.configs()["city-v1"] == FULL.scenario("city-v1").config
    assert main(["leaderboard", "tracks"]) == 0
    assert f"suite-v1       hash {FULL.hash}" in capsys.readouterr().out


@pytest.mark.slow
def test_ranked_by_the_held_out_aggregate_not_by_the_mean_score(db):
    store = Store(db)
    _entry(store, "good-at-training", nsw_train=0.85, nsw_heldout=0.50)  # the higher mean NSW over all rows
    _entry(store, "good-held-out", nsw_train=0.45, nsw_heldout=0.80)
    r = suite_report.ranking(store, TINY, baseline="good-at-training")
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
    again = suite_report.ranking(store, TINY, baseline="good-at-training").table
    assert again.equals(r.table), "the intervals are seeded: the same rows give the same digits"
    text = suite_report.render(r, "md")
    assert "| 1 | good-held-out | heuristic |" in text and "Mean normalized score per scenario" in text
    assert "| slow-64-v1 | heldout |" in text


@pytest.mark.slow
def test_submit_runs_every_scenario_and_resumes_and_the_html_shows_the_track(db, monkeypatch, capsys):
    monkeypatch.setitem(TRACKS, TINY.name, TINY)
    for policy in ("random", "heuristic"):
        out = submit(TINY, policy, policy, db=db, backend="serial", chunk_size=3)
        assert (out.status, out.stored_rows, out.new_rows) == ("complete", 6, 6), out.reason
    assert submit(TINY, "heuristic", "heuristic", db=db, backend="serial").new_rows == 0, "complete: nothing to run"
    rows, refused = Store(db).results(TINY)
    assert refused == [] and len(rows) == 12
    assert set(zip(rows["scenario"], rows["seed"], strict=True)) == set(TINY.units())
    assert rows[["decision_ms_p50", "cpu_s"]].notna().all().all()
    t = suite_report.ranking(Store(db), TINY).table.set_index("name")
    assert t.loc["heuristic", "rank"] == 1 and t.loc["random", "rank"] == 2
    assert t.loc["heuristic", "iqm_heldout"] > t.loc["random", "iqm_heldout"]
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db)]) == 0
    shown = capsys.readouterr().out
    assert "Held-out IQM [95% CI]" in shown and "Training IQM [95% CI]" in shown and "6/6" in shown
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--format", "html"]) == 0
    page = capsys.readouterr().out
    assert "<title>wfbench leaderboard: tiny-suite</title>" in page and "<th>Held-out IQM [95% CI]</th>" in page
    assert "<table id='scenarios'>" in page and "data:image/png;base64," in page
    assert "<td>slow-64-v1</td><td>heldout</td>" in page


def test_results_of_another_suite_version_are_refused(db):
    store = Store(db)
    _entry(store, "old", 0.6, 0.6)
    changed = SuiteTrack(name=TINY.name, description=TINY.description,
                         suite=Suite(name="suite-v1", version=1, description="seeds changed",
                                     scenarios=TINY.suite.scenarios, test_seeds=(0, 1, 2, 3)))
    assert changed.hash != TINY.hash
    rows, refused = store.results(changed)
    assert rows.empty and len(refused) == 6
    assert refused[0] == (f"result of 'old', scenario slow-64-v1, seed 0: made on another version of track "
                          f"tiny-suite (hash {TINY.hash}, current {changed.hash}); refused")
    r = suite_report.ranking(store, changed)
    assert r.table.loc[0, "rank"] is None and "0/8" in suite_report.render(r, "table")
