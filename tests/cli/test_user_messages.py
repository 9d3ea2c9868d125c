"""The first hour's messages (issue #45): a missing extra, a mistyped name and a warning are each one line.

- A command that needs an optional extra which is not installed says which extra to install,
  in one line, exit 2 (simulated: ``sys.modules[name] = None`` in a fresh interpreter).
- An unknown name suggests the closest allowed ones (``did you mean ...?``) and keeps the list.
- wfbench's own warnings print as ``wfbench: warning: ...``, with no file path or source line,
  and a suite run does not warn about running zero-shot on the held-out split.
- What the README's commands write lies where ``.gitignore`` covers it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from wfbench.cli import main
from wfbench.cli.common import EXIT_USAGE, with_suggestion

ROOT = Path(__file__).resolve().parents[2]


def _without(modules: list[str], argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """``wfbench ARGV`` in a fresh interpreter where importing each of ``modules`` fails, as if not installed."""
    code = (f"import sys\nfor m in {modules!r}:\n    sys.modules[m] = None\n"
            f"from wfbench.cli import main\nsys.exit(main({argv!r}))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(("modules", "argv", "command", "module", "extra"), [
    (["uvicorn"], ["serve", "--db", "board.sqlite"], "wfbench serve", "uvicorn", "server"),
    (["fastapi"], ["serve", "--db", "board.sqlite"], "wfbench serve", "fastapi", "server"),
    (["sqlalchemy"], ["serve", "--db", "board.sqlite"], "wfbench serve", "sqlalchemy", "server"),
    (["python_multipart", "multipart"], ["serve", "--db", "board.sqlite"], "wfbench serve", "python_multipart",
     "server"),
    (["sqlalchemy"], ["serve", "account", "add", "alice", "--db", "board.sqlite"], "wfbench serve account",
     "sqlalchemy", "server"),
    (["sqlalchemy"], ["worker", "--server", "board.sqlite", "--once"], "wfbench worker", "sqlalchemy", "server"),
    (["httpx"], ["leaderboard", "upload", "--server", "http://127.0.0.1:9", "--token", "t", "--policy", "m:P",
                 "--track", "paper-64"], "wfbench leaderboard upload", "httpx", "server"),
])
def test_missing_extra__is_one_line_naming_the_extra(modules, argv, command, module, extra, tmp_path):
    out = _without(modules, argv, tmp_path)
    assert out.returncode == EXIT_USAGE, out.stderr
    assert out.stderr == (f"wfbench: error: {command} needs {module}, which is not installed; install the {extra} "
                          f"extra: pip install 'wfbench[{extra}]'\n")
    assert not (tmp_path / "board.sqlite").exists()  # refused before the database is made


@pytest.mark.parametrize(("argv", "extra"), [
    (["train", "--scenario", "small"], "rl"),  # the existing line of the missing-torch case
    (["evaluate", "--policy", "ppo-joint", "--seeds", "1"], "rl"),
    (["evaluate", "--policy", "random", "--seeds", "1", "--backend", "ray"], "ray"),
])
def test_missing_extra__torch_and_ray_name_theirs(argv, extra, tmp_path):
    out = _without(["torch", "ray"], argv, tmp_path)
    assert out.returncode == EXIT_USAGE, out.stderr
    assert out.stderr.count("\n") == 1 and f"pip install 'wfbench[{extra}]'" in out.stderr, out.stderr


def test_missing_extra__other_import_errors_are_not_hidden():
    from wfbench.cli.common import missing_extra

    assert missing_extra(ModuleNotFoundError("No module named 'mypkg'", name="mypkg"), "wfbench evaluate") is None
    assert missing_extra(ImportError("cannot import name 'x'", name="torch"), "wfbench train") is None
    assert "the rl extra" in missing_extra(ModuleNotFoundError("x", name="torch.nn"), "wfbench train")


@pytest.mark.parametrize(("argv", "suggested", "kept"), [
    (["evaluate", "--policy", "heurstic", "--seeds", "2"], "; did you mean 'heuristic'", "available: random, "),
    (["evaluate", "--policy", "heuristic", "--scenario", "papr-64"], "; did you mean 'paper-64'", "(presets)"),
    (["evaluate", "--policy", "heuristic", "--suite", "suite-v2"], "; did you mean 'suite-v1'?", "allowed: suite-v1"),
    (["evaluate", "--policy", "heuristic", "--suite", "suite-v1", "--split", "heldot"], "; did you mean 'heldout'?",
     "allowed: train, heldout"),
    (["evaluate", "--policy", "heuristic", "--backend", "proces"], "; did you mean 'process'?", "available: serial"),
    (["evaluate", "--policy", "heuristic", "--seeds", "tset"], "; did you mean 'test'?", "a set name (test = 0-49"),
    (["reproduce", "tabel3"], "; did you mean 'table3'", "allowed: table2, table3"),
    (["leaderboard", "show", "--track", "papr-64"], "; did you mean 'paper-64'?", "available: paper-64"),
    (["train", "--algo", "ppp"], "did you mean 'ppo'?", "(choose from 'ppo'"),
    (["evalute"], "; did you mean 'evaluate'?", "(choose from 'evaluate'"),
    (["train", "--set", "total_steps=1", "--scenario", "small"], "procs; did you mean 'steps'",
     "settings: scenario, "),
])
def test_unknown_name__suggests_the_closest_and_keeps_the_list(argv, suggested, kept, capsys):
    assert main(argv) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and suggested in err and kept in err, err


def test_unknown_name__no_suggestion_when_nothing_is_close():
    message = "unknown policy 'zzzzzz'; available: random, heuristic"
    assert with_suggestion(message) == message
    assert with_suggestion("--seeds: 0 is not allowed; allowed: a count >= 1") == (
        "--seeds: 0 is not allowed; allowed: a count >= 1")
    assert with_suggestion("unknown track 'paper64'; available: paper-64, large") == (
        "unknown track 'paper64'; available: paper-64, large; did you mean 'paper-64'?")


def test_warning__wfbench_warnings_are_one_line_without_a_path(tmp_path):
    code = ("import warnings\nfrom wfbench.cli import _one_line_warnings\n"
            "from wfbench.policies.registry import ScenarioMismatchWarning\n_one_line_warnings()\n"
            "warnings.warn('trained elsewhere', ScenarioMismatchWarning)\nwarnings.warn('theirs', UserWarning)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    lines = out.stderr.splitlines()
    assert lines[0] == "wfbench: warning: trained elsewhere", out.stderr
    assert "UserWarning: theirs" in lines[1]  # other warnings keep Python's form


def zero_shot():
    """A random policy that says it was trained on paper-64-v1 only: every other scenario is zero-shot for it."""
    from wfbench.policies import get

    policy = get("random")
    policy.trained_on = ("paper-64-v1",)
    return policy


def test_warning__evaluate_suite_is_quiet_on_the_heldout_split():
    from wfbench.policies.registry import ScenarioMismatchWarning

    from tests.scenarios.test_suite import _mini
    from wfbench.harness.suite import evaluate_suite

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        evaluate_suite(zero_shot(), _mini(), [0])
    mismatch = [str(w.message) for w in caught if issubclass(w.category, ScenarioMismatchWarning)]
    assert len(mismatch) == 1 and "'small'" in mismatch[0], mismatch  # the training split's; none for large-v1


@pytest.mark.slow
def test_warning__a_suite_run_prints_one_line_per_training_scenario_and_none_for_heldout(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "wfbench.cli", "evaluate", "--policy",
                          "tests.cli.test_user_messages:zero_shot", "--suite", "suite-v1", "--seeds", "1",
                          "--backend", "serial", "--no-progress", "--act-timeout", "0"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert lines and all(line.startswith("wfbench: warning: policy ") for line in lines), out.stderr
    assert len(lines) == 7  # the training split's other seven scenarios; the held-out eight are zero-shot by design
    from wfbench.scenarios import get_suite

    for heldout in get_suite("suite-v1").scenarios:
        if heldout.split == "heldout":
            assert f"evaluated on {heldout.config.name!r}" not in out.stderr


def _written_by_readme() -> list[str]:
    """The files and folders the README's commands write in the checkout (their output options), and runs/."""
    readme = (ROOT / "README.md").read_text()
    paths = ["runs/ppo-joint-paper-64/best.pt"]  # wfbench train's default --run-dir
    for block in re.findall(r"```bash\n(.*?)```", readme, re.DOTALL):
        for line in block.splitlines():
            command = line.split("#")[0]
            paths += re.findall(r"--(?:out|json|plot|render)\s+(\S+)", command)
    return paths


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs git and a checkout")
def test_readme__commands_write_where_gitignore_covers_them():
    paths = _written_by_readme()
    assert "bench.json" in paths and "compare.png" in paths
    for path in paths:
        target = path if Path(path).suffix else f"{path}/file"  # a folder: anything written into it
        ignored = subprocess.run(["git", "check-ignore", "-q", "--no-index", target], cwd=ROOT).returncode == 0
        assert ignored, f"README.md's commands write {path}, which .gitignore does not cover"
