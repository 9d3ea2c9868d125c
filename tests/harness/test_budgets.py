"""What a result cost: budget columns on every evaluation row, the policy's own cost, and the leaderboard's
budget columns and filter (issue #27)."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
import torch
from wfbench.leaderboard.report import ranking, render
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.submit import submit
from wfbench.leaderboard.tracks import scenario_track
from wfbench.policies.solver import DEFAULT_TIME_LIMIT_S, AssignmentDispatch
from wfbench.solvers import assignment

from wfbench import policies
from wfbench.cli import main
from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import Execution
from wfbench.harness.budget import BUDGET_COLUMNS, NOT_RECORDED, machine, policy_budget, results_only
from wfbench.harness.evaluation import evaluate

SHORT = ScenarioConfig.preset("small").replace(name="budget-test", horizon=40)
TINY = scenario_track(name="tiny-budget", config=ScenarioConfig.preset("small").replace(name="tiny-budget", horizon=40),
                      public_seeds=(100, 101), test_seeds=(0, 1, 2, 3),
                      description="a small track for the budget tests",
                      references={"tiny-budget": (0.0, 1.0)})  # no published constants: normalized = NSW
SLEEP_S = 0.004


class Sleepy:
    """The heuristic, 4 ms late on every act call: at least 2 ms per decision in a batch of two."""

    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self):
        self.inner = policies.get("heuristic")

    def reset(self, seeds):
        self.inner.reset(seeds)

    def act(self, obs):
        time.sleep(SLEEP_S)
        return self.inner.act(obs)


def test_evaluate__every_row_carries_its_cost_and_the_frame_its_machine():
    compiled = evaluate("random", SHORT, 3)
    stepped = evaluate(Sleepy(), SHORT, [0, 1])
    for df in (compiled, stepped):
        assert set(BUDGET_COLUMNS) <= set(df.columns)
        assert (df[list(BUDGET_COLUMNS)] >= 0).all().all() and np.isfinite(df[list(BUDGET_COLUMNS)]).all().all()
        assert (df["decision_ms_p99"] >= df["decision_ms_p50"]).all()
        budget = df.attrs["budget"]
        assert budget["machine"] == machine() and budget["machine"]["cores"] >= 1
        assert {"platform", "cpu", "python", "numba", "torch"} <= set(budget["machine"])
        assert budget["backend"] == "serial" and budget["workers"] == 1
    assert compiled.attrs["budget"]["timing"] == "rollout" and stepped.attrs["budget"]["timing"] == "act"
    assert compiled.attrs["budget"]["policy"] == {"kind": "builtin"}
    # one call for two environments is two decisions of half its time each
    assert (stepped["decision_ms_p50"] >= SLEEP_S * 1e3 / 2).all()
    assert (stepped["cpu_s"] < stepped["decision_ms_p50"] * 1e-3 * SHORT.horizon).all(), "sleeping is no CPU time"


def test_budget_columns_are_measurements_kept_out_of_result_comparisons():
    a, b = evaluate(Sleepy(), SHORT, [0, 1]), evaluate(Sleepy(), SHORT, [0, 1])
    assert not set(BUDGET_COLUMNS) & set(results_only(a).columns)
    assert results_only(a).equals(results_only(b)), "the same seeds give the same results whatever they cost"
    assert list(results_only(a).columns) == [c for c in a.columns if c not in BUDGET_COLUMNS]


def test_policy_budget__shipped_networks_tuned_files_and_solver_limits():
    shipped = policy_budget("ppo-joint")
    assert shipped["kind"] == "learned" and shipped["train_env_steps"] == 512_000
    assert shipped["train_wall_s"] == NOT_RECORDED and shipped["train_hardware"] == NOT_RECORDED
    tuned = policy_budget("heuristic-tuned")
    assert tuned == {"kind": "tuned", "trials": 200, "tuned_on": "paper-64"}
    milp = policies.Composite(AssignmentDispatch("milp", time_limit_s=0.25), "threshold", "spatial")
    assert policy_budget(None, milp) == {"kind": "other", "solver_time_limit_s": {"dispatch": 0.25}}
    named = policy_budget("assignment-milp+threshold+spatial", policies.get("assignment-milp+threshold+spatial"))
    assert named["solver_time_limit_s"] == {"dispatch": DEFAULT_TIME_LIMIT_S}
    assert "solver_time_limit_s" not in policy_budget("solver", policies.get("solver")), "compiled: no solver call"


def test_solver_backed_dispatch_passes_its_stated_limit_to_every_solve(monkeypatch):
    seen = []
    real = assignment.solve

    def spy(*args, **kwargs):
        seen.append(kwargs.get("time_limit"))
        return real(*args, **kwargs)

    monkeypatch.setattr(assignment, "solve", spy)
    evaluate(policies.Composite(AssignmentDispatch("milp", time_limit_s=0.5), "threshold", "spatial"), SHORT, [0])
    assert seen and set(seen) == {0.5}
    with pytest.raises(ValueError, match=r"time_limit_s=0 is not allowed; allowed: seconds > 0"):
        AssignmentDispatch("milp", time_limit_s=0)
    assert AssignmentDispatch("exact").time_limit_s is None, "scipy's exact method is polynomial: no limit"


def test_a_new_checkpoint_records_its_training_wall_time_and_hardware(tmp_path):
    from wfbench.train.ppo import TrainConfig, Trainer

    cfg = TrainConfig(scenario="small", model="tiny", num_envs=2, num_steps=8, steps=2 * 8, epochs=1, minibatches=1,
                      eval_every=0, checkpoint_every=1, run_dir=str(tmp_path / "run"), seed=3)
    Trainer(cfg, progress=False, log=False).train()
    ckpt = torch.load(tmp_path / "run" / "latest.pt", weights_only=False)
    assert ckpt["train_wall_s"] > 0 and f"{machine()['cores']} cores" in ckpt["train_hardware"]
    b = policy_budget(f"ppo:{tmp_path / 'run' / 'latest.pt'}")
    assert b["train_env_steps"] == 16 and b["train_wall_s"] == ckpt["train_wall_s"]
    assert b["train_hardware"] == ckpt["train_hardware"]


def _rows(nsw, p99, cpu, machine_line="test machine"):
    return [{"seed": s, "workforce_cost": 10.0, "utilization": 0.5, "downtime": 0.1, "nsw": nsw, "episode_length": 40,
             "invalid_actions": 0, "decision_ms_p50": p99 / 2, "decision_ms_p99": p99, "cpu_s": cpu,
             "machine": machine_line} for s in TINY.test_seeds]


def _entry(store, name, rows, budget=None):
    sub, _ = store.open_submission(TINY, name, "heuristic", "me", "0", fingerprint=name,
                                   budget=json.dumps(budget or {"kind": "builtin"}))
    store.add_results(sub, "0", rows)
    store.set_status(sub.id, "done")


@pytest.mark.slow
def test_ranking_within_a_budget_leaves_out_what_exceeds_it_and_says_why(tmp_path):
    store = Store(tmp_path / "lb.sqlite")
    _entry(store, "fast", _rows(0.6, p99=0.5, cpu=0.01))
    _entry(store, "slow-but-good", _rows(0.8, p99=25.0, cpu=2.0),
           {"kind": "learned", "train_env_steps": 512_000, "train_wall_s": 7200.0, "train_hardware": "8 cores"})
    _entry(store, "unmeasured", [{**r, "decision_ms_p50": math.nan, "decision_ms_p99": math.nan}
                                 for r in _rows(0.7, p99=0, cpu=0.01)])
    full = ranking(store, TINY).table.set_index("name")
    assert full["rank"].to_dict() == {"slow-but-good": 1, "unmeasured": 2, "fast": 3}
    assert full.loc["slow-but-good", "decision_ms_p99"] == 25.0 and full.loc["fast", "cpu_s"] == 0.01
    assert full.loc["slow-but-good", "cost"] == "512,000 env-steps; wall 2.00 h; hardware 8 cores"
    r = ranking(store, TINY, max_decision_ms=10)
    t = r.table.set_index("name")
    assert t.loc["fast", "rank"] == 1 and t["rank"].isna().sum() == 2
    assert r.left_out == ["slow-but-good: p99 25 ms per decision > 10 ms", "unmeasured: no decision time recorded"]
    text = render(r, "table")
    assert "outside the budget: p99 25 ms per decision > 10 ms" in text
    assert "ranked only within the budget of at most 10 ms per decision (p99)" in text
    assert [x.loc["fast", "rank"] for x in [ranking(store, TINY, max_cpu_s=1).table.set_index("name")]] == [2]
    # a measurement edited in the store no longer matches its row's digest
    with store.engine.begin() as c:
        c.exec_driver_sql("UPDATE rows SET cpu_s = 0.001 WHERE seed = 0 AND submission_id = "
                          "(SELECT id FROM submissions WHERE name = 'slow-but-good')")
    assert any("do not match its digest" in m for m in store.results(TINY)[1])


def test_rows_stored_before_budgets_stay_valid_and_show_no_measurement(tmp_path):
    from tests.leaderboard.test_leaderboard import TINY as STORED  # the track the schema-4 store holds
    from tests.leaderboard.test_schema4_import import write_schema4

    path = tmp_path / "old.sqlite"
    write_schema4(path)  # its legacy entry 'old' has no budget on its rows and states none
    store = Store(path)
    rows, _ = store.results(STORED)
    old = rows[rows["name"] == "old"]
    assert len(old) == 4 and old[list(BUDGET_COLUMNS)].isna().all().all() and old["machine"].isna().all()
    r = ranking(store, STORED)
    assert r.table.set_index("name").loc["old", "cost"] == "not recorded"
    assert "| - | - | - | not recorded |" in render(r, "md"), "no measurement: dashes, not zeros"
    store.close()


@pytest.mark.slow
def test_submit_stores_the_cost_and_show_prints_and_filters_it(tmp_path, capsys, monkeypatch):
    db = tmp_path / "lb.sqlite"
    monkeypatch.setattr("wfbench.leaderboard.tracks.TRACKS", {TINY.name: TINY})
    for policy, name in (("random", "random"), ("tests.harness.test_budgets:Sleepy", "sleepy")):
        out = submit(TINY, policy, name, db=db, execution=Execution(backend="serial", chunk_size=2))
        assert out.status == "complete", out.reason
    rows = Store(db).results(TINY)[0]
    assert rows[list(BUDGET_COLUMNS)].notna().all().all() and rows["machine"].str.contains("serial x1").all()
    assert (rows.loc[rows["name"] == "sleepy", "decision_ms_p50"] >= SLEEP_S * 1e3 / 2).all()
    assert json.loads(Store(db).find(TINY.name, "random").budget) == {"kind": "builtin"}
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--baseline", "random"]) == 0
    shown = capsys.readouterr().out
    assert "ms per decision p50 / p99" in shown and "CPU s per episode" in shown and machine()["cpu"] in shown
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--max-decision-ms", "1"]) == 0
    out, err = capsys.readouterr()
    assert "wfbench: left out by the budget: sleepy: p99 " in err and "ms per decision > 1 ms" in err
    assert "left out: sleepy" in out
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--format", "html"]) == 0
    assert "<th>ms per decision p50 / p99</th>" in capsys.readouterr().out
    assert main(["leaderboard", "show", "--track", TINY.name, "--db", str(db), "--max-decision-ms", "-1"]) == 2
    assert "argument --max-decision-ms: -1 is not allowed; allowed: a number > 0" in capsys.readouterr().err
