"""Candidate totals from committed suite pieces, taken only when the piece was made by this code.

A suite piece is ``FOLDER/cache/POLICY/SCENARIO.csv`` (one row per seed, its ``nsw`` the episode
mean) with a ``.json`` holding the suite scenario's ``hash``, the ``seeds`` and the
``provenance`` (``wfbench.reproduce.provenance``: the ``commit`` that made it and whether the
tree was ``dirty``). The replaying oracle reads the pieces of its candidates without a network
(whose totals do not depend on the batch) from :func:`folders`. **Provenance matches the
code** when the piece names a commit, was not made from a dirty tree, and every file that
decides the candidate's episodes (:func:`wfbench.policies.oracle.episodes.decisive_files`: the
import closure of its objects' modules and of the simulator) has at that commit the bytes it
has here, as git stores them (blob ids), and the files besides code it reads (a checkpoint, a
tuned file: :func:`wfbench.policies.registry.input_files`) are those the piece recorded, with
the same sha256. A piece that covers some asked seeds and does not
match is passed over in the checkout's own ``docs/results`` (the oracle plays those seeds);
in a folder named by ``$WFBENCH_ORACLE_PIECES`` it raises :class:`PieceMismatch`, one line
naming the piece. Either way the oracle never mixes codes.
``docs/hindsight.md``, "Replayed, not played again".
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.core.config import ScenarioConfig
from wfbench.core.jit import ROOT
from wfbench.core.seeds import describe as describe_seeds
from wfbench.scenarios.pieces import parts_of, piece_path, read_meta, read_rows

ENV = "WFBENCH_ORACLE_PIECES"  # folders of suite runs (os.pathsep between them), or "off"
OFF = ("off", "0", "false", "no", "")
RESULTS = "docs/results"  # where a checkout keeps its committed suite runs


class PieceMismatch(ValueError):
    """A committed piece the oracle was asked to use was made by other code than this."""


def folders() -> tuple[list[Path], bool]:
    """The suite runs whose pieces the replaying oracle reads, and whether they were asked for by name.

    ``$WFBENCH_ORACLE_PIECES`` names them (asked for: a piece there from other code fails);
    ``off`` (or empty) names none. Unset: every folder of ``docs/results`` with a ``cache/`` in
    the checkout the code runs from (none in an installed copy), whose pieces from other code
    are passed over.
    """
    value = os.environ.get(ENV)
    if value is not None:
        if value.strip().lower() in OFF:
            return [], True
        return [Path(p) for p in value.split(os.pathsep) if p], True
    results = ROOT / RESULTS
    return (sorted(p for p in results.iterdir() if (p / "cache").is_dir()) if results.is_dir() else []), False


@cache
def _suite_scenarios(text: str) -> tuple[tuple[str, str], ...]:
    """(id, hash) of every suite scenario whose config's canonical JSON is ``text``."""
    from wfbench.scenarios import SUITES, get_suite

    out = []
    for name in SUITES:
        for sc in get_suite(name).scenarios:
            if json.dumps(sc.config.to_dict(), sort_keys=True) == text:
                out.append((sc.id, sc.hash))
    return tuple(out)


def find(policy: str, config: ScenarioConfig, seeds: np.ndarray) -> list[tuple[Path, dict, pd.DataFrame]]:
    """The pieces of ``policy`` on ``config`` (a suite scenario) that hold any of ``seeds``: (csv, meta, rows)."""
    out = []
    scenarios = _suite_scenarios(json.dumps(config.to_dict(), sort_keys=True))
    wanted = set(np.asarray(seeds).tolist())
    for folder in folders()[0]:
        for sc_id, sc_hash in scenarios:
            path = piece_path(folder, policy, sc_id)
            meta = read_meta(path, sc_hash)
            if meta is None or not wanted & set(meta.get("seeds", [])):
                continue
            out.append((path, meta, read_rows(path)))
    return out


def _git(*args: str, data: bytes | None = None) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], input=data, capture_output=True, check=True).stdout.decode()


@cache
def _repository() -> bool:
    try:
        return Path(_git("rev-parse", "--show-toplevel").strip()).resolve() == ROOT.resolve()
    except (OSError, subprocess.CalledProcessError):
        return False


def mismatch(meta: dict, files: list[str], inputs: Sequence[Path] | None = None) -> str | None:
    """Why a piece's provenance does not match this code, or None.

    ``files``: the repository paths of the code that decides it; ``inputs``, when given: the
    other files it reads now (:func:`wfbench.policies.registry.input_files`: a checkpoint, a
    tuned file), which the piece's recorded ``inputs`` must name, each with the sha256 it has now.
    """
    prov = meta.get("provenance") or {}
    commit = prov.get("commit")
    if not commit:
        return "it records no commit"
    if prov.get("dirty") is True:
        return f"it was made from a dirty tree at {commit[:12]}"
    if not _repository():
        return "this code is not a git checkout, so its files cannot be compared with the commit"
    return _differs(commit, tuple(files)) or (None if inputs is None else _inputs_differ(prov, inputs))


def _inputs_differ(prov: dict, inputs: Sequence[Path]) -> str | None:
    """Why the files a piece recorded reading (``inputs``: path -> sha256) are not those read now, or None."""
    recorded = {(ROOT / name).resolve(): sha for name, sha in (prov.get("inputs") or {}).items()}
    for path in inputs:
        name = os.path.relpath(path.resolve(), ROOT.resolve()).replace(os.sep, "/")
        if path.resolve() not in recorded:
            return f"it does not record reading {name}"
        stat = path.stat()
        if _sha256(path.resolve(), stat.st_mtime_ns, stat.st_size) != recorded[path.resolve()]:
            return f"{name} differs from the one it was made with"
    if extra := sorted(set(recorded) - {p.resolve() for p in inputs}):
        return f"it was made reading {os.path.relpath(extra[0], ROOT.resolve())}, which this policy does not read"
    return None


@cache
def _sha256(path: Path, mtime_ns: int, size: int) -> str:
    """A file's sha256, read once per version of it (its modification time and size key the cache)."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


@cache
def _differs(commit: str, files: tuple[str, ...]) -> str | None:
    try:
        listing = _git("ls-tree", "-r", "--full-tree", commit, "--", *files)
    except subprocess.CalledProcessError:
        return f"its commit {commit[:12]} is not in this repository"
    then = {line.split("\t", 1)[1]: line.split()[2] for line in listing.splitlines()}
    now = _git("hash-object", "--", *files).split()
    for path, blob in zip(files, now, strict=True):
        if then.get(path) != blob:
            return f"{path} differs from its commit {commit[:12]}"
    return None


def _parts(meta: dict) -> list[tuple[set[int], dict]]:
    """Each part of a piece: the seeds it played and the part itself, whose ``provenance`` :func:`mismatch` judges.

    A piece extended by the seeds it lacked (``wfbench.reproduce.pieces.obtain``) keeps a
    ``parts`` list, one per run that played some of its seeds; its top-level provenance is
    the last run's only, so a seed is judged by the part that played it.
    """
    return [({int(x) for x in part.get("seeds", [])}, part) for part in parts_of(meta)]


def scores(policy: str, config: ScenarioConfig, seeds: np.ndarray, files: list[str],
           who: str = "oracle", inputs: Sequence[Path] | None = None, batch: bool = False,
           ) -> tuple[np.ndarray, dict[int, Path], list[tuple[Path, str]]]:
    """The committed mean NSW of ``seeds`` (NaN where no piece has it), the piece of each row that has one.

    And the pieces passed over, with why: those from other code found in the default folders.
    A piece extended over several runs is judged part by part: each seed by the provenance of
    the run that played it (:func:`_parts`). ``inputs``: the files besides code the policy
    reads now, which a piece must have recorded with the same bytes (:func:`mismatch`).
    ``batch``: the policy's totals depend on its batch (a network), so only a part that
    recorded playing ``seeds``, in this order, as one of its ``batches`` is read.

    Raises:
        PieceMismatch: a piece holding some of the seeds, in a folder asked for by name, does not
            match this code (one line, naming it, and the seeds when a part of it does not).
    """
    seeds = np.asarray(seeds, dtype=np.int64)
    out = np.full(seeds.size, np.nan)
    where: dict[int, Path] = {}
    skipped: list[tuple[Path, str]] = []
    asked = folders()[1]
    wanted = set(seeds.tolist())
    for path, meta, rows in find(policy, config, seeds):
        by_seed = dict(zip(rows["seed"].astype(int).tolist(), rows["nsw"].astype(float).tolist(), strict=True))
        usable: set[int] = set()
        for part_seeds, part in _parts(meta):
            if batch and seeds.tolist() not in (part.get("batches") or []):
                continue  # another batch: a network's totals there may differ in the last bit
            covered = part_seeds & set(by_seed)
            why = mismatch(part, files, inputs)
            if why is None:
                usable |= covered
                continue
            if not covered & wanted:
                continue
            if "parts" in meta:
                why = f"{why}, seeds {describe_seeds(sorted(covered))}"
            if asked:
                raise PieceMismatch(f"{who}: the piece {path} of {policy!r} was not made by this code ({why}); "
                                    f"recompute it (wfbench reproduce suite) or leave its folder out of ${ENV}")
            skipped.append((path, why))
        for i, s in enumerate(seeds.tolist()):
            if i not in where and s in usable:
                out[i], where[i] = by_seed[s], path
    return out, where, skipped


__all__ = ["ENV", "PieceMismatch", "find", "folders", "mismatch", "scores"]
