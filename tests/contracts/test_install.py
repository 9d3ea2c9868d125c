"""One installed name: wfbench works from a folder that has its own ``policies/``, ``solvers/`` and ``leaderboard/``.

pyproject.toml installs the checkout's top-level folders as ``wfbench.policies``,
``wfbench.solvers`` and ``wfbench.leaderboard`` ([tool.setuptools] package-dir). Before
issue #33 they were installed as top-level ``policies``, ``solvers`` and ``leaderboard``,
and a user's folder of the same name (the usual name in an RL project) shadowed them:
``import wfbench`` failed. Here the user's packages raise on import, so any import of them
by wfbench fails the command that made it.
"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
WFBENCH = Path(sys.executable).with_name("wfbench")
SHADOWS = ("policies", "solvers", "leaderboard")


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A user's project folder whose own ``policies``, ``solvers`` and ``leaderboard`` packages must never load."""
    folder = tmp_path_factory.mktemp("my-rl-project")
    for name in SHADOWS:
        (folder / name).mkdir()
        (folder / name / "__init__.py").write_text(f"raise ImportError('the user\\'s own {name} was imported')\n")
    return folder


def _run(args, cwd, timeout=300):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_import_wfbench_from_a_folder_with_its_own_policies_solvers_and_leaderboard(project):
    code = ("import sys, wfbench, wfbench.policies, wfbench.solvers, wfbench.leaderboard.store; "
            "import wfbench.harness.evaluation, wfbench.envs; "
            "print([m.__file__ for m in (wfbench.policies, wfbench.solvers, wfbench.leaderboard)]); "
            f"assert not any(n in sys.modules for n in {SHADOWS!r}), 'a top-level name was imported'")
    run = _run([sys.executable, "-c", code], project)
    assert run.returncode == 0, run.stderr
    for name in SHADOWS:
        assert str(project / name) not in run.stdout and f"{name}{'/'}__init__.py" in run.stdout, run.stdout


@pytest.mark.parametrize("args", [
    ["evaluate", "--policy", "heuristic", "--scenario", "small", "--seeds", "2", "--backend", "serial"],
    ["compare", "--policies", "random,heuristic", "--scenario", "small", "--seeds", "2"],
    ["simulate", "--policy", "solver", "--scenario", "small", "--seed", "0"],
    ["policies"],
    ["scenarios"],
    ["suite", "show", "suite-v1"],
    ["leaderboard", "tracks"],
    ["reproduce", "--help"],
    ["train", "--help"],
    ["tune", "--help"],
    ["bench", "--help"],
], ids=lambda a: a[0])
@pytest.mark.slow
def test_every_command_runs_from_that_folder(project, args):
    run = _run([str(WFBENCH), *args], project)
    assert run.returncode == 0, f"wfbench {' '.join(args)} failed in a folder with its own packages:\n{run.stderr}"
    assert "the user's own" not in run.stderr


@pytest.mark.slow
def test_the_checkout_root_on_the_path_still_finds_the_mapped_packages():
    # python run from the checkout puts its root first on sys.path: wfbench is the folder, and the editable
    # install's finder maps wfbench.policies to policies/ (setuptools' editable finder answers after the path)
    run = _run([sys.executable, "-c", "import wfbench.policies.registry as r; print(r.__file__)"], ROOT)
    assert run.returncode == 0, run.stderr
    assert Path(run.stdout.strip()) == ROOT / "policies" / "registry.py"
