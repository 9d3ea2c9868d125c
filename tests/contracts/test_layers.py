"""The import layers of docs/design.md: checked statically by import-linter and at run time.

The contracts live in pyproject.toml ([tool.importlinter]): the layers top to bottom,
the order inside policies, solvers importing nothing of ours, and no cycles between the
modules of any package. A failure names the offending import chain; move the import
down a layer or move the code up, and say where in docs/design.md.
"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_layers__import_contracts_hold():
    # tools/lint_imports.py runs import-linter over the tree as installed (policies/ as wfbench/policies/, ...)
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "lint_imports.py")], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, f"an import breaks the layers of docs/design.md:\n{run.stdout}\n{run.stderr}"
    assert "0 broken" in run.stdout, run.stdout


def test_layers__no_contract_excuses_an_import():
    # issue #45: the core resolved scenario names by importing wfbench.scenarios (the tree's one cycle), excused
    # three times; names are now resolved where they enter (docs/design.md), and an excuse would hide the next one
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    excused = {c["name"]: c["ignore_imports"] for c in contracts if c.get("ignore_imports")}
    assert excused == {}, f"import-linter contracts that excuse imports: {excused}"


def _folder(name: str, package_dir: dict[str, str]) -> Path:
    """The checkout's folder of package ``name`` (pyproject.toml's package-dir maps wfbench.policies to policies/)."""
    top = max((n for n in ("wfbench", *package_dir) if name == n or name.startswith(n + ".")), key=len)
    return ROOT / package_dir.get(top, top) / Path(*name[len(top):].split(".")[1:])


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


def _data_packages(pyproject: dict) -> set[str]:
    """The data packages: package-data folders without code (namespace packages of shipped files, issue #45)."""
    setuptools = pyproject["tool"]["setuptools"]
    return {name for name in setuptools["package-data"]
            if not (_folder(name, setuptools["package-dir"]) / "__init__.py").exists()}


def test_layers__every_package_is_installed_and_has_an_exhaustive_contract():
    # an exhaustive contract fails on a module that is in none of its layers; a package without such a contract
    # (a new subpackage) would let its modules import each other in any order, unseen; a package missing from
    # [tool.setuptools] packages is missing from the wheel. A package of one module (wfbench.policies.tuned: its
    # __init__.py beside its shipped files) has nothing to order.
    import tomllib

    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    contracts = pyproject["tool"]["importlinter"]["contracts"]
    covered = {c for contract in contracts if contract.get("exhaustive") for c in contract.get("containers", [])}
    packages = _packages()
    package_dir = pyproject["tool"]["setuptools"]["package-dir"]
    ordered = {p for p in packages
               if any(f.name != "__init__.py" or f.parent != _folder(p, package_dir)
                      for f in _folder(p, package_dir).rglob("*.py"))}
    assert ordered - covered == set(), (f"packages without an exhaustive import-linter contract in pyproject.toml: "
                                        f"{sorted(ordered - covered)}; give each its layers (docs/design.md, Layers)")
    assert {"wfbench", "wfbench.core", "wfbench.cli", "wfbench.train", "wfbench.leaderboard",
            "wfbench.policies", "wfbench.harness", "wfbench.analysis", "wfbench.scenarios"} <= covered
    data = _data_packages(pyproject)
    for name in data:  # a folder of files and no code, or it would need a contract too
        folder = _folder(name, package_dir)
        assert folder.is_dir() and not any(folder.rglob("*.py")), f"data package {name}: {folder} holds code or is gone"
    listed = set(pyproject["tool"]["setuptools"]["packages"])
    assert listed == packages | data, (f"[tool.setuptools] packages differs from the tree: "
                                       f"{sorted(listed ^ (packages | data))}")


def test_layers__importing_the_core_pulls_nothing_above_it():
    above = ("'wfbench.policies', 'wfbench.leaderboard', 'wfbench.solvers', 'wfbench.harness', 'wfbench.envs', "
             "'wfbench.cli', 'wfbench.train'")
    code = ("import sys, wfbench; import wfbench.core.simulator, wfbench.core.observe, wfbench.core.placement; "
            f"above = sorted(m for m in sys.modules if m.startswith(({above}))); print(above); assert not above")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"importing the simulator core imported layers above it: {run.stdout}{run.stderr}"


@pytest.mark.slow
def test_layers__evaluate_stays_the_function_after_its_module_is_imported():
    code = ("import wfbench.harness.compare, wfbench.harness.evaluation, wfbench; "
            "assert callable(wfbench.evaluate) and wfbench.evaluate.__module__ == 'wfbench.harness.evaluation'")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
