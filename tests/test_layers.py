"""The import layers of docs/design.md: checked statically by import-linter and at run time.

The contracts live in pyproject.toml ([tool.importlinter]): the layers top to bottom,
the order inside policies, solvers importing nothing of ours, and no cycles between the
modules of any package. A failure names the offending import chain; move the import
down a layer or move the code up, and say where in docs/design.md.
"""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_layers__import_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    run = subprocess.run([str(lint), "--config", str(ROOT / "pyproject.toml"), "--no-cache"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"an import breaks the layers of docs/design.md:\n{run.stdout}\n{run.stderr}"
    assert "0 broken" in run.stdout, run.stdout


def test_layers__every_package_has_an_exhaustive_contract():
    # an exhaustive contract fails on a module that is in none of its layers; a package without such a contract
    # (a new subpackage) would let its modules import each other in any order, unseen
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    covered = {c for contract in contracts if contract.get("exhaustive") for c in contract.get("containers", [])}
    tops = ("wfbench", "policies", "solvers", "leaderboard")
    inits = [init for top in tops for init in (ROOT / top).rglob("__init__.py")]
    packages = {".".join(init.parent.relative_to(ROOT).parts) for init in inits}
    assert packages - covered == set(), (f"packages without an exhaustive import-linter contract in pyproject.toml: "
                                         f"{sorted(packages - covered)}; give each its layers (docs/design.md, Layers)")
    assert {"wfbench", "wfbench.core", "wfbench.cli", "wfbench.train", "leaderboard", "policies"} <= covered


def test_layers__importing_the_core_pulls_nothing_above_it():
    code = ("import sys, wfbench; import wfbench.core.simulator, wfbench.core.observe, wfbench.core.placement; "
            "above = sorted(m for m in sys.modules if m.split('.')[0] in ('policies', 'leaderboard', 'solvers') "
            "or m in ('wfbench.evaluation', 'wfbench.envs', 'wfbench.runner', 'wfbench.backends', 'wfbench.cli')); "
            "print(above); assert not above")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"importing the simulator core imported layers above it: {run.stdout}{run.stderr}"


def test_layers__evaluate_stays_the_function_after_its_module_is_imported():
    code = ("import wfbench.compare, wfbench.evaluation, wfbench; "
            "assert callable(wfbench.evaluate) and wfbench.evaluate.__module__ == 'wfbench.evaluation'")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
