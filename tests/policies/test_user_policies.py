"""A user's own policy: found in the current folder, its failures named by file and line, contained by limits.

The hostile policies live in ``tests/data/user_policies/hostile.py``; the leaderboard's
isolation test (tests/leaderboard/test_leaderboard.py) submits each of them.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from wfbench.cli import main
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.harness.guard import PolicyError, PolicyLoadError, load_policy

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "user_policies"
HOSTILE = DATA / "hostile.py"
SPEC = "tests.data.user_policies.hostile"


def line_of(marker: str, path: Path = HOSTILE) -> int:
    return next(i for i, text in enumerate(path.read_text().splitlines(), 1) if marker in text)


def run_cli(argv, capsys):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


SMALL = ["--scenario", "small", "--seeds", "2", "--backend", "serial", "--no-progress"]


@pytest.mark.slow
def test_policy_in_the_current_folder_loads_by_module_attr(tmp_path):
    run = subprocess.run(
        [str(Path(sys.executable).with_name("wfbench")), "evaluate", "--policy", "mypkg.mod:MyPolicy", "--scenario",
         "small", "--seeds", "4", "--backend", "process", "--workers", "2", "--format", "json", "--no-progress"],
        cwd=DATA, capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    mine = json.loads(run.stdout)["summary"]
    heuristic = evaluate("heuristic", "small", 4)
    for kpi, values in mine.items():
        assert values["mean"] == pytest.approx(heuristic[kpi].mean(), rel=1e-12), kpi


def test_the_policy_check_a_submitter_runs_passes_the_users_policy_and_names_a_malformed_action():
    from wfbench.testing import PolicyCheckError, check_policy

    check_policy("tests.data.user_policies.mypkg.mod:MyPolicy", "small", seeds=[0, 1])
    with pytest.raises(PolicyCheckError) as err:
        check_policy(f"{SPEC}:Garbage", "small", seeds=[0, 1])
    assert str(err.value) == (f"policy '{SPEC}:Garbage' at step 0 returned a malformed action: dispatch action has "
                              "shape (), expected (2, 8)")


def test_a_raising_policy_names_its_file_line_and_spec_and_exits_1(capsys):
    code, out, err = run_cli(["evaluate", "--policy", f"{SPEC}:Raises", *SMALL], capsys)
    assert code == 1
    assert err == (f"wfbench: error: policy '{SPEC}:Raises' failed in act at {HOSTILE}:{line_of('boom at step 3')}: "
                   "RuntimeError: boom at step 3 (--traceback prints the whole trace)\n")
    code, out, err = run_cli(["evaluate", "--policy", f"{SPEC}:Raises", *SMALL, "--traceback"], capsys)
    assert code == 1
    assert err.startswith("Traceback (most recent call last):") and 'raise RuntimeError("boom at step 3")' in err
    assert err.splitlines()[-1].startswith(f"wfbench: error: policy '{SPEC}:Raises' failed in act at {HOSTILE}:")


def test_a_malformed_action_names_the_policy_and_its_act(capsys):
    code, out, err = run_cli(["evaluate", "--policy", f"{SPEC}:Garbage", *SMALL], capsys)
    assert code == 1 and err.count("\n") == 1
    assert (f"policy '{SPEC}:Garbage' returned a malformed action at step 0 (its act is at "
            f"{HOSTILE}:{line_of('class Garbage') + 1}): ActionError: dispatch action has shape ()") in err


@pytest.mark.parametrize(("name", "marker"), [("Hangs", "time.sleep(3600)"), ("Spins", "a busy loop")])
def test_a_hanging_policy_is_stopped_by_the_act_timeout(capsys, name, marker):
    code, out, err = run_cli(["evaluate", "--policy", f"{SPEC}:{name}", *SMALL, "--act-timeout", "1"], capsys)
    assert code == 1 and err.count("\n") == 1
    assert (f"policy '{SPEC}:{name}' did not return from act within the act timeout of 1 s "
            f"(stopped at {HOSTILE}:{line_of(marker, HOSTILE)})") in err


def test_time_under_the_numba_compiler_lock_does_not_count():
    # what a first call into wfbench's kernels does on a cold cache: hold numba's lock while it compiles
    df = evaluate(f"{SPEC}:CompilesSlowly", "small", [0], act_timeout_s=0.5)
    assert len(df) == 1
    with pytest.raises(PolicyError, match="did not return from act within the act timeout of 0.5 s"):
        evaluate(f"{SPEC}:SleepsOnce", "small", [0], act_timeout_s=0.5)


@pytest.mark.slow
def test_a_policy_defined_in_a_script_fails_in_a_worker_with_its_own_line():
    with pytest.raises(PolicyError) as err:
        evaluate(f"{SPEC}:Raises", "small", 4, execution=Execution(backend="process", workers=2))
    assert str(err.value) == (f"policy '{SPEC}:Raises' failed in act at {HOSTILE}:{line_of('boom at step 3')}: "
                              "RuntimeError: boom at step 3")
    assert f'File "{HOSTILE}", line {line_of("boom at step 3")}, in act' in err.value.trace, "the worker's trace"


def test_errors_while_loading_a_user_policy():
    with pytest.raises(PolicyLoadError, match="cannot import module 'tests.data.user_policies.nope'"):
        load_policy("tests.data.user_policies.nope:X")
    with pytest.raises(PolicyError, match=rf"policy '{SPEC}:BrokenInit' could not be loaded: ZeroDivisionError: "
                                          rf".* at {HOSTILE}:{line_of('1 / 0  # the constructor')}"):
        load_policy(f"{SPEC}:BrokenInit")
    with pytest.raises(ValueError, match=r"act_timeout_s = -1 is not allowed; allowed: seconds > 0, or 0/None"):
        evaluate(f"{SPEC}:Raises", "small", 1, act_timeout_s=-1)
    assert load_policy("heuristic").guard is None, "built-in registry policies run unguarded"
    assert load_policy(f"{SPEC}:Raises", act_timeout_s=0).guard.act_timeout_s is None


def test_usage_mistakes_exit_2(capsys):
    code, out, err = run_cli(["evaluate", "--policy", "nope.mod:X", *SMALL], capsys)
    assert code == 2 and err.startswith("wfbench: error: cannot import module 'nope.mod'") and err.count("\n") == 1
    code, out, err = run_cli(["evaluate", "--policy", f"{SPEC}:Raises", *SMALL, "--act-timeout", "-2"], capsys)
    assert code == 2 and "allowed: seconds > 0, or 0 for no limit" in err and err.count("\n") == 1


def test_show_does_not_create_a_missing_store(tmp_path, capsys):
    missing = tmp_path / "missing.db"
    code, out, err = run_cli(["leaderboard", "show", "--db", str(missing)], capsys)
    assert code == 2 and err == (f"wfbench: error: store {missing} does not exist; pass --db with the file that "
                                 "'wfbench leaderboard submit' or 'baselines' wrote, or run one of them first\n")
    assert not missing.exists()


@pytest.mark.slow
def test_a_hostile_submission_ends_with_one_line_from_the_command_line(tmp_path, capsys, monkeypatch):
    from wfbench.leaderboard.tracks import TRACKS

    from tests.leaderboard.test_leaderboard import TINY

    monkeypatch.setitem(TRACKS, TINY.name, TINY)
    code, out, err = run_cli(["leaderboard", "submit", "--policy", f"{SPEC}:Hangs", "--name", "hangs", "--track",
                              TINY.name, "--db", str(tmp_path / "lb.sqlite"), "--backend", "serial",
                              "--act-timeout", "2", "--wall-time", "120", "--no-progress"], capsys)
    assert code == 1 and err.count("\n") == 1, err
    assert err.startswith(f"wfbench: submission 'hangs' on tiny-test failed: policy '{SPEC}:Hangs' did not return "
                          f"from act within the act timeout of 2 s (stopped at {HOSTILE}:")
    assert "--traceback prints the whole trace" in err  # and not the two-minute wall time that stopped it


def test_a_failure_in_code_sent_by_value_is_named_at_the_policys_file(tmp_path):
    """Code cloudpickle sends to a worker is named <dynamic-code>; the error names the class's file instead.

    The end-to-end check (a script's policy in a process pool) is tests/harness/test_backends_script.py; it needs
    the cloudpickle that renames files. This one makes such code here, on any version.
    """
    from wfbench.harness.guard import DYNAMIC_CODE, Guard

    namespace: dict = {}
    exec(compile("def act(obs):\n    x = 1\n    return obs['missing']\n", DYNAMIC_CODE, "exec"), namespace)
    script = str(tmp_path / "my_script.py")
    with pytest.raises(PolicyError, match=r"failed in act at .*my_script\.py:3: KeyError"):
        Guard("mine", None, source=script).call("act", namespace["act"], {})
    with pytest.raises(PolicyError, match=r"failed in act at <dynamic-code>:3: KeyError"):
        Guard("mine", None).call("act", namespace["act"], {})  # without the class's file: the frame as it is
