"""import-linter over the tree as it is installed: ``policies/`` as ``wfbench/policies/``, and so on.

pyproject.toml installs the checkout's top-level folders ``policies/``, ``solvers/`` and
``leaderboard/`` as ``wfbench.policies``, ``wfbench.solvers`` and ``wfbench.leaderboard``
(``[tool.setuptools] package-dir``). Grimp, which import-linter builds its graph with, walks
a package's own folder, so it would not find ``wfbench.policies`` in ``policies/``. This
script copies the Python files into a temporary folder laid out as the wheel lays them out
and runs ``lint-imports`` there, with the contracts of pyproject.toml. Usage::

    python tools/lint_imports.py          # exit status and output are lint-imports'

tests/contracts/test_layers.py runs it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def stage(into: Path) -> Path:
    """Copy every ``.py`` of the installed packages into ``into``, where the wheel would put them."""
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    package_dir = setuptools.get("package-dir", {})
    for package in setuptools["packages"]:
        top = max((p for p in package_dir if package == p or package.startswith(p + ".")), key=len, default=None)
        source = (ROOT / package_dir[top] / Path(*package[len(top) + 1:].split("."))) if top else \
            ROOT / Path(*package.split("."))
        target = into / Path(*package.split("."))
        target.mkdir(parents=True, exist_ok=True)
        for py in source.glob("*.py"):
            shutil.copy2(py, target / py.name)
    return into


def main() -> int:
    lint = Path(sys.executable).with_name("lint-imports")
    with tempfile.TemporaryDirectory(prefix="wfbench-layers-") as tmp:
        stage(Path(tmp))
        env = {**os.environ, "PYTHONPATH": tmp}
        return subprocess.run([str(lint), str(ROOT / "pyproject.toml"), "--no-cache"], cwd=tmp,
                              env=env).returncode


if __name__ == "__main__":
    sys.exit(main())
