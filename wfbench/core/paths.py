"""Where wfbench's packages and shipped data files are, in a checkout (editable) and in an installed wheel alike.

The checkout's top-level ``policies/``, ``solvers/`` and ``leaderboard/`` import as
``wfbench.policies``, ... (pyproject.toml's package-dir); a wheel has them under
``wfbench/``. Nothing here guesses from ``__file__``: a package's folder is what the import
system finds for it (:func:`package_dir`), and a shipped file is read through
:mod:`importlib.resources` (:func:`data_path`); docs/design.md, "Where is it", lists the data packages.
"""

from __future__ import annotations

import importlib.util
from functools import cache
from importlib.resources import files
from pathlib import Path

__all__ = ["CHECKPOINTS", "REAL_DATA", "TUNED", "data_path", "package_dir"]

# the data packages (pyproject.toml lists them; their files are package data)
CHECKPOINTS = "wfbench.policies.neural.checkpoints"  # policies/neural/checkpoints/: the shipped networks
TUNED = "wfbench.policies.tuned"  # policies/tuned/: the shipped tuned-policy files beside the code that reads them
REAL_DATA = "wfbench.core.data"  # wfbench/core/data/: the real-data presets' committed files


@cache
def package_dir(name: str) -> Path:
    """The folder package ``name`` imports from (resolved), found by the import system without importing it."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError(f"{name!r} is not an importable package", name=name)
    return Path(next(iter(spec.submodule_search_locations))).resolve()


def data_path(package: str, name: str = "") -> Path:
    """The file ``name`` of data package ``package`` (the package's folder without a name), as a filesystem path.

    wfbench installs as plain files (a checkout, an editable install or an unpacked wheel),
    so the resource is a real path: torch, sha256 and the error messages take it as it is.
    """
    if not name:
        return package_dir(package)
    path = files(package).joinpath(name)  # a namespace package's MultiplexedPath answers with a Path too
    return path if isinstance(path, Path) else Path(str(path))
