"""The import layers of docs/design.md: checked statically by import-linter and at run time.

The contracts live in pyproject.toml ([tool.importlinter]): the layers top to bottom,
the order inside policies, solvers importing nothing of ours, and no cycles between the
modules of any package. A failure names the offending import chain; move the import
down a layer or move the code up, and say where in docs/design.md.
"""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_layers__import_contracts_hold():
    # tools/lint_imports.py runs import-linter over the tree as installed (policies/ as wfbench/policies/, ...)
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "lint_imports.py")], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, f"an import breaks the layers of docs/design.md:\n{run.stdout}\n{run.stderr}"
    assert "0 broken" in run.stdout, run.stdout


def _packages() -> set[str]:
    """Every package of the tree, by its installed name (pyproject.toml's package-dir maps the folders)."""
    import tomllib

    package_dir = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    folders = {"wfbench": "wfbench"} | package_dir
    found = set()
    for name, folder in folders.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            found.add(".".join([name, *init.parent.relative_to(ROOT / folder).parts]))
    return found


def test_layers__every_package_is_installed_and_has_an_exhaustive_contract():
    # an exhaustive contract fails on a module that is in none of its layers; a package without such a contract
    # (a new subpackage) would let its modules import each other in any order, unseen; a package missing from
    # [tool.setuptools] packages is missing from the wheel
    import tomllib

    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    contracts = pyproject["tool"]["importlinter"]["contracts"]
    covered = {c for contract in contracts if contract.get("exhaustive") for c in contract.get("containers", [])}
    packages = _packages()
    assert packages - covered == set(), (f"packages without an exhaustive import-linter contract in pyproject.toml: "
                                         f"{sorted(packages - covered)}; give each its layers (docs/design.md, Layers)")
    assert {"wfbench", "wfbench.core", "wfbench.cli", "wfbench.train", "wfbench.leaderboard",
            "wfbench.policies", "wfbench.harness", "wfbench.analysis", "wfbench.scenarios"} <= covered
    listed = set(pyproject["tool"]["setuptools"]["packages"])
    assert listed == packages, f"[tool.setuptools] packages differs from the tree: {sorted(listed ^ packages)}"


def test_layers__importing_the_core_pulls_nothing_above_it():
    above = ("'wfbench.policies', 'wfbench.leaderboard', 'wfbench.solvers', 'wfbench.harness', 'wfbench.envs', "
             "'wfbench.cli', 'wfbench.train'")
    code = ("import sys, wfbench; import wfbench.core.simulator, wfbench.core.observe, wfbench.core.placement; "
            f"above = sorted(m for m in sys.modules if m.startswith(({above}))); print(above); assert not above")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"importing the simulator core imported layers above it: {run.stdout}{run.stderr}"


def test_layers__evaluate_stays_the_function_after_its_module_is_imported():
    code = ("import wfbench.harness.compare, wfbench.harness.evaluation, wfbench; "
            "assert callable(wfbench.evaluate) and wfbench.evaluate.__module__ == 'wfbench.harness.evaluation'")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
