"""A wheel installed outside the checkout runs every kind of shipped file, with the numbers of the checkout.

Issue #45: the data folders (``policies/neural/checkpoints/``, ``policies/tuned/``,
``wfbench/core/data/``) are packages read through ``importlib.resources``, and nothing
works out "checkout or installed?" from ``__file__`` (``wfbench.core.paths``). Here the
wheel is built from the tracked files (a stale ``build/`` cannot leak into it), with no
setuptools warning, installed with ``pip install --target`` into a temporary folder, and
run from another temporary folder with that folder first on ``PYTHONPATH``: the editable
install's finder answers after the path, and the child checks that ``wfbench.policies``
is the wheel's. It evaluates a network (``ppo-general``), a tuned file (``solver-tuned``)
and a real-data scenario (``real-benelux``), and each table equals this process's
(the editable checkout) bit for bit.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from importlib.metadata import version
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
# (policy, scenario, seeds): a shipped network, a shipped tuned file, a real-data preset
RUNS = [("ppo-general", "small", 1), ("solver-tuned", "small", 2), ("heuristic", "real-benelux", 1)]
TIMES = ("decision_ms_p50", "decision_ms_p99", "cpu_s")  # measured, not computed: every other column is compared
SHIPPED = ("wfbench/policies/tuned/__init__.py", "wfbench/policies/tuned/solver-paper-64.json",
           "wfbench/policies/neural/checkpoints/ppo-general.pt", "wfbench/core/data/real-benelux-sites.csv",
           "wfbench/reproduce/paper.toml", "wfbench/scenarios/suite-v1.json",
           # the hosted board's Alembic environment: it upgrades a board's database at every start
           "wfbench/leaderboard/board/migrations/env.py", "wfbench/leaderboard/board/migrations/script.py.mako",
           "wfbench/leaderboard/board/migrations/versions/r0001_first_schema.py")

CHILD = """
import sys
from pathlib import Path
site, out = Path(sys.argv[1]).resolve(), Path(sys.argv[2])
import wfbench, wfbench.policies
from wfbench.policies import registry
for mod in (wfbench, wfbench.policies):
    if not Path(mod.__file__).resolve().is_relative_to(site):
        sys.exit(f"{mod.__name__} imported from {mod.__file__}, not from the wheel in {site}")
print("policies:", wfbench.policies.__file__, "checkpoints:", registry.CHECKPOINT_DIR)
runs = RUNS
for i, (policy, scenario, seeds) in enumerate(runs):
    wfbench.evaluate(policy, scenario, seeds=seeds).to_pickle(out / f"{i}.pkl")
"""


def _sources(into: Path) -> Path:
    """The checkout's tracked and new (not ignored) files, copied: what a fresh clone builds."""
    listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                            capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():  # a file deleted but not yet staged is listed too
            (into / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, into / name)
    return into


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    """The built wheel and pip's verbose build output."""
    assert int(version("setuptools").split(".")[0]) >= 77, "pyproject.toml's build-system needs setuptools >= 77"
    tmp = tmp_path_factory.mktemp("wheel")
    src = _sources(tmp / "src")
    # the venv's setuptools (>= 77, as build-system requires) without build isolation: no index needed
    run = subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation", "-v",
                          "-w", str(tmp / "dist")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    (whl,) = (tmp / "dist").glob("wfbench-*.whl")
    return whl, run.stdout + run.stderr


@pytest.mark.slow
def test_wheel__builds_without_a_setuptools_warning(wheel):
    _, log = wheel
    # setuptools' warnings are classes (SetuptoolsDeprecationWarning:, _Warning:); pip's own say "WARNING:"
    found = [line for line in log.splitlines() if re.search(r"\w*Warning:|package init file", line)]
    assert found == [], "\n".join(found)


@pytest.mark.slow
def test_wheel__holds_the_data_packages_and_the_license(wheel):
    whl, _ = wheel
    with zipfile.ZipFile(whl) as z:
        names = set(z.namelist())
        (metadata,) = [n for n in names if n.endswith(".dist-info/METADATA")]
        text = z.read(metadata).decode()
    assert set(SHIPPED) <= names, sorted(set(SHIPPED) - names)
    assert "wfbench/policies/tuned.py" not in names  # the module is the package tuned/ (its __init__.py)
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names), "LICENSE is not in the wheel"
    assert "License-Expression: Apache-2.0" in text


@pytest.mark.slow
def test_wheel__installed_outside_the_checkout_runs_every_shipped_kind_with_the_same_numbers(wheel, tmp_path):
    import wfbench

    whl, _ = wheel
    site, out, cwd = tmp_path / "site", tmp_path / "out", tmp_path / "elsewhere"
    for d in (out, cwd):
        d.mkdir()
    run = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-compile", "--target", str(site),
                          str(whl)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"PYTHONPATH": str(site)}
    child = [sys.executable, "-c", CHILD.replace("RUNS", repr(RUNS)), str(site), str(out)]
    run = subprocess.run(child, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-6000:]
    assert str(site.resolve()) in run.stdout, run.stdout
    for i, (policy, scenario, seeds) in enumerate(RUNS):
        installed, here = pd.read_pickle(out / f"{i}.pkl"), wfbench.evaluate(policy, scenario, seeds=seeds)
        numbers = [c for c in here.columns if c not in TIMES]
        assert list(installed.columns) == list(here.columns)
        pd.testing.assert_frame_equal(installed[numbers], here[numbers], check_exact=True,
                                      obj=f"{policy} on {scenario}")
