"""``wfbench evaluate --suite`` prints what the API makes (suite_cells, suite_summary), with evaluate's act timeout."""

from __future__ import annotations

import json

import pytest

from tests.scenarios.test_suite import _mini
from wfbench.analysis.tables import markdown_table
from wfbench.cli import main
from wfbench.harness import evaluation, guard
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S
from wfbench.harness.suite import evaluate_suite, suite_cells, suite_summary


@pytest.fixture
def mini_run(monkeypatch):
    """The suite run of the command, on a two-scenario suite: the frame it got and the timeout it asked for."""
    real, seen = evaluate_suite, {}

    def run(policy, suite, seeds, **kw):
        seen["act_timeout_s"] = kw["act_timeout_s"]
        seen["df"] = real(policy, _mini(), seeds, split=kw["split"],
                          act_timeout_s=kw["act_timeout_s"])
        return seen["df"]

    monkeypatch.setattr("wfbench.harness.suite.evaluate_suite", run)
    return seen


@pytest.mark.slow
def test_the_command_prints_the_api_s_table_and_json(mini_run, capsys):
    argv = ["evaluate", "--policy", "heuristic", "--suite", "suite-v1", "--seeds", "2", "--no-progress"]
    assert main([*argv, "--format", "md"]) == 0
    out = capsys.readouterr().out
    header, rows = suite_cells(mini_run["df"])
    assert header[:2] == ["Scenario", "Split"] and [r[0] for r in rows] == ["small-v1", "large-v1"]
    assert out.startswith(markdown_table(header, rows) + "\n")
    assert main([*argv, "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data == json.loads(json.dumps(suite_summary(mini_run["df"], [0, 1]), default=float))
    assert data["policy"] == "heuristic" and list(data["scenarios"]) == ["small-v1", "large-v1"]


@pytest.mark.parametrize("flag, limit", [([], DEFAULT_ACT_TIMEOUT_S), (["--act-timeout", "0"], None),
                                         (["--act-timeout", "3"], 3.0)])
@pytest.mark.slow
def test_one_scenario_and_a_suite_get_the_same_act_timeout(flag, limit, mini_run, monkeypatch, capsys):
    loaded = []
    real = guard.load_policy

    def spy(policy, act_timeout_s=DEFAULT_ACT_TIMEOUT_S):
        loaded.append(real(policy, act_timeout_s))
        return loaded[-1]

    monkeypatch.setattr(evaluation, "load_policy", spy)
    monkeypatch.setattr(guard, "load_policy", spy)
    base = ["evaluate", "--policy", "tests.lb_policies:Slow", "--seeds", "1", "--backend", "serial", "--no-progress",
            *flag]
    assert main([*base, "--scenario", "small"]) == 0
    assert main([*base, "--suite", "suite-v1", "--split", "train"]) == 0
    assert mini_run["act_timeout_s"] == limit
    evaluate_suite("tests.lb_policies:Slow", _mini(), [0], split="train")  # the API's default
    evaluation.evaluate("tests.lb_policies:Slow", "small", [0])
    limits = [lp.guard.act_timeout_s for lp in dict.fromkeys(loaded)]  # evaluate_suite hands its load on
    assert limits[0] == limits[1] == limit and limits[2] == limits[3] == DEFAULT_ACT_TIMEOUT_S
    capsys.readouterr()
