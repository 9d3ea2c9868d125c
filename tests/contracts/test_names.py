"""The same scenario names work in every command and function (issue #33; docs/scenarios.md, "Naming a scenario").

A preset (``small``), a config file and a suite's versioned id (``small-v1``) are one
scenario: each command and function resolves them through ``wfbench.scenarios.resolve``
and runs the same world. Tiny seeds and steps keep it fast.
"""

from __future__ import annotations

import json

import gymnasium
import pytest

import wfbench
from wfbench.cli import main
from wfbench.core.config import ScenarioConfig

NAMES = ("preset", "file", "versioned")


@pytest.fixture
def scenario(request, tmp_path) -> str:
    """The name of ``small`` in one of its forms."""
    kind = request.param
    if kind == "file":
        path = tmp_path / "small.toml"
        ScenarioConfig.preset("small").save(path)
        return str(path)
    return {"preset": "small", "versioned": "small-v1"}[kind]


@pytest.mark.parametrize("scenario", NAMES, indirect=True)
def test_names__every_function_and_command_takes_a_preset_a_file_and_a_versioned_id(scenario, tmp_path, capsys):
    df = wfbench.evaluate("heuristic", scenario, seeds=[3])
    assert df.attrs["scenario"] == "small"
    nsw = float(df["nsw"].iloc[0])

    assert main(["evaluate", "--policy", "heuristic", "--scenario", scenario, "--seeds", "3", "--seed-start", "0",
                 "--backend", "serial", "--format", "json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["scenario"] == "small"

    assert main(["compare", "--policies", "heuristic,random", "--scenario", scenario, "--seeds", "1",
                 "--backend", "serial", "--no-progress"]) == 0
    assert "heuristic" in capsys.readouterr().out

    assert main(["simulate", "--scenario", scenario, "--seed", "3", "--steps", "5", "--no-progress"]) == 0
    capsys.readouterr()

    assert main(["tune", "heuristic", "--scenario", scenario, "--trials", "1", "--seeds", "public:1",
                 "--study-db", str(tmp_path / "s.db"), "--out", str(tmp_path / "t.json"), "--no-progress"]) == 0
    assert json.loads((tmp_path / "t.json").read_text())["scenario"] == "small"
    capsys.readouterr()

    env = gymnasium.make("wfbench/Workforce-v0", scenario=scenario)
    env.reset(seed=3)
    assert env.unwrapped.config == ScenarioConfig.preset("small")
    par = wfbench.parallel_env(scenario=scenario)
    par.reset(seed=3)
    assert par.config == ScenarioConfig.preset("small")
    assert wfbench.evaluate("heuristic", ScenarioConfig.preset("small"), seeds=[3])["nsw"].iloc[0] == nsw


@pytest.mark.slow
@pytest.mark.parametrize("scenario", NAMES, indirect=True)
def test_names__bench_and_train_take_them_too(scenario, tmp_path, capsys):
    pytest.importorskip("torch")
    assert main(["bench", "--scenario", scenario, "--quick"]) == 0
    assert "scenario: small" in capsys.readouterr().out
    run = tmp_path / "run"
    assert main(["train", "--scenario", scenario, "--model", "tiny", "--num-envs", "2", "--num-steps", "8",
                 "--steps", "16", "--epochs", "1", "--eval-every", "0", "--run-dir", str(run), "--no-progress",
                 "--no-tensorboard"]) == 0
    assert (run / "best.pt").is_file()


@pytest.mark.parametrize("spec", ["small-v1,paper-64", "suite-v1:train"])
def test_names__several_worlds_take_the_same_names_and_suites(spec):
    from wfbench.scenarios.resolve import resolve_worlds

    worlds = resolve_worlds(spec)
    assert all(w.suite == "suite-v1" and w.split == "train" for w in worlds)
    assert worlds[0].name == "small-v1" and worlds[0].config == ScenarioConfig.preset("small")


@pytest.mark.parametrize("argv", [
    ["evaluate", "--policy", "random", "--scenario", "moon"],
    ["simulate", "--scenario", "moon"],
    ["bench", "--scenario", "moon"],
    ["tune", "heuristic", "--scenario", "moon"],
    ["compare", "--policies", "random", "--scenario", "moon"],
])
def test_names__a_bad_name_is_one_line_that_says_what_is_allowed(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown scenario 'moon'" in err
    assert "paper-64" in err and "paper-64-v1" in err and ".toml/.json" in err
