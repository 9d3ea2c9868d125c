"""What made a committed result: the commit, a hash of the code and a hash of the files a policy reads.

Each suite piece's ``.json`` (beside ``cache/POLICY/SCENARIO.csv``) has a ``hash`` and ``seeds``
that decide reuse, and a ``provenance``: ``commit`` and ``dirty``; ``code_sha256``
(:func:`code_sha256`, every file under ``wfbench/``, ``policies/`` and ``solvers/`` but the
checkpoints, the same from git's objects of a commit, :func:`code_sha256_at`); and ``inputs``,
the sha256 of each checkpoint or tuned file the policy reads; and ``machine`` (:func:`machine`:
the versions of the packages that compute, and the CPU's vector extensions, which pick the
BLAS kernel). It does not decide reuse (a new
commit would discard every piece): :mod:`wfbench.reproduce.verify` catches a changed behaviour
by recomputing pieces (``docs/suite.md``, "What moved in issue #42").
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from collections.abc import Iterable
from functools import cache
from pathlib import Path
from typing import Any

from wfbench.core.paths import package_dir

# the top-level folders whose files compute results, by their name in the repository
CODE_ROOTS = ("wfbench", "policies", "solvers")
_SUFFIXES = (".py", ".json", ".toml", ".csv")
_SKIP_PARTS = ("__pycache__", "checkpoints")


def _roots() -> dict[str, Path]:
    return {"wfbench": package_dir("wfbench"), "policies": package_dir("wfbench.policies"),
            "solvers": package_dir("wfbench.solvers")}


def _counts(path: str) -> bool:
    parts = path.split("/")
    return path.endswith(_SUFFIXES) and parts[0] in CODE_ROOTS and not any(p in _SKIP_PARTS for p in parts)


def _digest(files: Iterable[tuple[str, bytes]]) -> str:
    h = hashlib.sha256()
    for name, data in sorted(files):
        h.update(f"{name}\0{hashlib.sha256(data).hexdigest()}\n".encode())
    return h.hexdigest()


@cache
def code_sha256() -> str:
    """The hash of the code that computes results, as installed (a checkout, editable or not)."""
    files = []
    for top, root in _roots().items():
        for p in root.rglob("*"):
            rel = f"{top}/{p.relative_to(root).as_posix()}"
            if p.is_file() and _counts(rel):
                files.append((rel, p.read_bytes()))
    return _digest(files)


def _git(repo: Path, *args: str, data: bytes | None = None) -> bytes:
    return subprocess.run(["git", "-C", str(repo), *args], input=data, capture_output=True, check=True).stdout


def code_sha256_at(repo: Path, commit: str) -> str:
    """:func:`code_sha256` of the tree of ``commit`` in the git repository ``repo``, from git's objects."""
    listing = _git(repo, "ls-tree", "-r", "--full-tree", commit, "--", *CODE_ROOTS).decode().splitlines()
    entries = [(line.split("\t", 1)[1], line.split()[2]) for line in listing if line.split()[1] == "blob"]
    entries = [(path, sha) for path, sha in entries if _counts(path)]
    out = _git(repo, "cat-file", "--batch", data="".join(f"{sha}\n" for _, sha in entries).encode())
    files, at = [], 0
    for path, _ in entries:
        header_end = out.index(b"\n", at)
        size = int(out[at:header_end].split()[2])
        files.append((path, out[header_end + 1:header_end + 1 + size]))
        at = header_end + 1 + size + 1
    return _digest(files)


@cache
def repository() -> Path | None:
    """The git checkout the code runs from, or None (an installed copy)."""
    root = _roots()["wfbench"].parent
    try:
        top = _git(root, "rev-parse", "--show-toplevel").decode().strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return Path(top) if Path(top).resolve() == root.resolve() else None


@cache
def commit() -> tuple[str | None, bool]:
    """The checkout's commit and whether the files that compute results differ from it (None, False outside one).

    Taken once per process, as :func:`code_sha256` is: a long run records the code it started
    with (:func:`start`), not what the checkout holds when a piece ends.
    """
    repo = repository()
    if repo is None:
        return None, False
    head = _git(repo, "rev-parse", "HEAD").decode().strip()
    dirty = bool(_git(repo, "status", "--porcelain", "--untracked-files=no", "--", *CODE_ROOTS).strip())
    return head, dirty


def file_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _repo_name(path: Path) -> str:
    """A file's path in the repository (``policies/neural/checkpoints/x.pt``), or as given outside it."""
    roots = _roots()
    p = path.resolve()
    for top, root in roots.items():
        if p.is_relative_to(root.resolve()):
            return f"{top}/{p.relative_to(root.resolve()).as_posix()}"
    return str(path)


def policy_inputs(policy: str) -> dict[str, str]:
    """The sha256 of each file whose bytes decide ``policy`` (its checkpoint or tuned file), by repository path.

    :func:`wfbench.policies.registry.input_files`: a lookahead's base's file too, and a
    best-in-hindsight oracle's candidates'. A composite of built-ins reads none.
    """
    from wfbench.policies import registry

    if policy == "bound":
        return {}
    return dict(sorted((_repo_name(f), file_sha256(f)) for f in registry.input_files(policy)))


def start() -> None:
    """Take the commit and the code's hash now (a suite or frontier run calls it before it plays anything)."""
    commit()
    code_sha256()


# the packages whose versions can move a result's bits: the simulator's compiler, the arrays and their BLAS, the
# MILP (SciPy's HiGHS, and highspy's), the networks
MACHINE_PACKAGES = ("numpy", "numba", "scipy", "highspy", "torch")
# the CPU's vector extensions: OpenBLAS picks its kernels by them (its AVX-512 dot rounds a 3-term sum otherwise)
CPU_FLAGS = ("avx2", "avx512f")


@cache
def machine() -> dict[str, Any]:
    """What the code ran on: Python's and :data:`MACHINE_PACKAGES`' versions, :data:`CPU_FLAGS`, ``OPENBLAS_CORETYPE``.

    Recorded beside the commit so that a piece whose numbers another machine does not give back
    says where it was made (docs/hindsight.md: a calibrated MPC's plan moved with the BLAS kernel).
    """
    from importlib.metadata import PackageNotFoundError, version

    def installed(name: str) -> str | None:
        try:
            return version(name)
        except PackageNotFoundError:
            return None

    flags: set[str] = set()
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((set(line.split(":", 1)[1].split()) for line in f if line.startswith("flags")), set())
    except OSError:
        pass
    return {"python": platform.python_version(), "packages": {p: installed(p) for p in MACHINE_PACKAGES},
            "arch": platform.machine(), "cpu_flags": [f for f in CPU_FLAGS if f in flags],
            "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE")}


def current(policy: str) -> dict[str, Any]:
    """The provenance of a piece of ``policy`` computed now, by this code."""
    head, dirty = commit()
    return {"commit": head, "dirty": dirty, "code_sha256": code_sha256(), "inputs": policy_inputs(policy),
            "machine": machine()}
