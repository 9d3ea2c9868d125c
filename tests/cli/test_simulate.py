"""``wfbench simulate`` over :func:`wfbench.simulate`: one episode, a user's policy run through its guard."""

import subprocess
import sys
from pathlib import Path

import pytest

import wfbench
from wfbench.cli import main
from wfbench.harness.guard import PolicyError

ROOT = Path(__file__).resolve().parents[2]
WFBENCH = str(Path(sys.executable).with_name("wfbench"))
FAILS = {  # failing policy of tests/lb_policies.py -> what its one line says
    "Raises": "failed in act at",
    "Hangs": "did not return from act within the act timeout of 1 s",
    "Garbage": "returned a malformed action",
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", FAILS)
def test_a_failing_user_policy_is_one_line_and_status_1(kind):
    run = subprocess.run([WFBENCH, "simulate", "--policy", f"tests.lb_policies:{kind}", "--scenario", "small",
                          "--steps", "10", "--act-timeout", "1", "--no-progress"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    # a cold numba cache (an edited core) adds its one compile notice before the run: that line is not the failure's
    lines = [line for line in run.stderr.splitlines() if not line.startswith("wfbench: compiling ")]
    assert len(lines) == 1, run.stderr  # no "Traceback"
    assert lines[0].startswith("wfbench: error: policy 'tests.lb_policies:") and FAILS[kind] in lines[0], lines[0]
    assert "lb_policies.py" in lines[0] or kind != "Raises", "the line names the user's file"


def test_traceback_prints_the_whole_trace_then_the_line(capsys):
    assert main(["simulate", "--policy", "tests.lb_policies:Raises", "--scenario", "small", "--steps", "10",
                 "--no-progress", "--traceback"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback") and "boom at step 5" in err
    assert err.splitlines()[-1].startswith("wfbench: error: policy 'tests.lb_policies:Raises' failed in act at")


def test_a_spec_that_names_no_policy_is_a_usage_error(capsys):
    assert main(["simulate", "--policy", "no-such-policy", "--scenario", "small", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wfbench: error: ") and "no-such-policy" in err and len(err.splitlines()) == 1


def test_simulate_in_python_raises_the_policy_error():
    with pytest.raises(PolicyError, match="failed in act at .*lb_policies.py"):
        wfbench.simulate("tests.lb_policies:Raises", "small", 0, steps=10)


def test_a_whole_episode_has_the_kpis_of_its_evaluation():
    episode = wfbench.simulate("heuristic", "small", 3)
    row = wfbench.evaluate("heuristic", "small", seeds=[3]).iloc[0]
    assert episode.steps == episode.scenario.horizon and episode.frames == 0 and episode.gif is None
    assert episode.kpis == pytest.approx({k: row[k] for k in episode.kpis}, rel=1e-12)


def test_steps_stop_the_episode_and_the_command_prints_them(capsys):
    episode = wfbench.simulate("random", "small", 0, steps=7)
    assert episode.steps == 7 and episode.policy == "random"
    assert main(["simulate", "--policy", "random", "--scenario", "small", "--steps", "7", "--no-progress"]) == 0
    out = capsys.readouterr().out.strip()
    assert out == "small seed 0, random, 7 steps: " + ", ".join(f"{k}={v:.4g}" for k, v in episode.kpis.items())


@pytest.mark.slow
def test_a_hindsight_oracle_is_handed_the_scenario():
    """The oracle reads the future: like the runner, simulate attaches it before reset (it raised before)."""
    assert wfbench.simulate("oracle", "small", 0, steps=3).steps == 3


@pytest.mark.parametrize("kwargs, says", [
    ({"steps": 0}, "steps = 0 is not allowed; allowed: an integer >= 1"),
    ({"seed": -1}, "seed = -1 is not allowed; allowed: an integer >= 0"),
    ({"every": 1.5}, "every = 1.5 is not allowed; allowed: an integer >= 1"),
    ({"render": "/no/such/folder/x.gif"}, "render '/no/such/folder/x.gif': folder '/no/such/folder' does not exist"),
])
def test_bad_arguments_are_one_line_value_errors(kwargs, says):
    with pytest.raises(ValueError) as info:
        wfbench.simulate("heuristic", "small", **kwargs)
    assert str(info.value) == says
