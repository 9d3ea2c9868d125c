"""mkdocs hook: the API pages read the sources laid out as installed (``policies/`` as ``wfbench/policies/``).

pyproject.toml installs the checkout's top-level folders ``policies/``, ``solvers/`` and
``leaderboard/`` as ``wfbench.policies``, ``wfbench.solvers`` and ``wfbench.leaderboard``.
Griffe, which mkdocstrings reads the sources with, looks for ``wfbench.policies`` inside
the folder ``wfbench/`` and would not find it. Before each build this hook copies the
sources into a temporary folder laid out as the wheel lays them out (the same staging as
``tools/lint_imports.py``) and points mkdocstrings' Python handler at it.
"""

from __future__ import annotations

import importlib.util
import shutil
import tempfile
from pathlib import Path

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("_wfbench_lint_imports", ROOT / "tools" / "lint_imports.py")
_lint_imports = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_lint_imports)

_TREE: Path | None = None


@event_priority(100)  # before mkdocstrings makes its Python handler from this config
def on_config(config):
    global _TREE
    _TREE = Path(tempfile.mkdtemp(prefix="wfbench-docs-tree-"))
    config.plugins["mkdocstrings"].config.handlers["python"]["paths"] = [str(_TREE)]
    return config


def on_pre_build(config):
    # again on every rebuild of `mkdocs serve`, so an edited docstring shows
    for child in _TREE.iterdir():
        shutil.rmtree(child)
    _lint_imports.stage(_TREE)


def on_shutdown():
    if _TREE is not None:
        shutil.rmtree(_TREE, ignore_errors=True)

