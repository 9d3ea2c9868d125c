"""Recorded episodes of candidates played through ``act``: per seed, the NSW total and the actions that made it.

A lookahead episode costs seconds to minutes of CPU; the replaying references
(:data:`wfbench.policies.oracle.references.REPLAYING`) play one once and keep it here. An
:class:`Episode` holds what :class:`wfbench.policies.oracle.best.BestInHindsight` replays: the
dispatches that send somebody, each step's workforce code and the positioning row the
simulator reads. The store sits beside the totals cache (:func:`wfbench.policies.oracle.cache.directory`,
one ``episode-KEY`` folder per key, one compressed ``.npz`` per entry, written atomically: a
``city`` episode's positioning rows are a thousand wide and nearly all zero) and is keyed
like it (:func:`candidate_key`): the code, the scenario, and what decides the policy's actions
(each object's class and every plain setting, a kernel's code and parameters, a network's
checkpoint). A candidate without a network plays a seed the same in any batch (tested), so its
entries are keyed by the seed; one with a network by the seed and the batch
(:func:`wfbench.policies.oracle.cache.batch_keys`). ``docs/hindsight.md``, "Replayed, not played again".
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from wfbench.policies.oracle import cache

from wfbench.core.config import ScenarioConfig
from wfbench.core.jit import PACKAGES, ROOT, dependencies, source_digest

PREFIX = "episode-"
_MEMORY: dict[str, dict[tuple[int, bytes], Episode]] = {}
_PLAIN = (bool, int, float, str, type(None), np.integer, np.floating, np.bool_)
_DEPTH = 4  # how deep the identity walks policy objects (a lookahead's base's parts are at depth 2)


@dataclass
class Episode:
    """One seed's episode: its NSW total and its actions, stored sparsely (see the module docstring)."""

    total: float
    workforce: np.ndarray  # (T,) int8 each step's workforce code
    disp_t: np.ndarray  # (n,) int32 step of each dispatch that sends somebody
    disp_f: np.ndarray  # (n,) int32 its facility slot
    disp_v: np.ndarray  # (n,) int32 its person slot
    pos_t: np.ndarray  # (m,) int32 each step that hires or lets go
    pos: np.ndarray  # (m, M) float64 the positioning row the simulator reads on that step


class Recording:
    """The actions of one candidate's episode over a batch, stored sparsely (see the module docstring)."""

    def __init__(self, B: int, M: int, N: int, horizon: int):
        self.B, self.M, self.N = B, M, N
        self.workforce = np.zeros((horizon, B), dtype=np.int8)
        self._dispatch: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]] = []
        self._positioning: dict[tuple[int, int], np.ndarray] = {}

    def add(self, t: int, d: np.ndarray, w: np.ndarray, p: np.ndarray) -> None:
        b, f = np.nonzero(d != self.N)
        if b.size:
            self._dispatch.append((t, b.astype(np.int32), f.astype(np.int32), d[b, f].astype(np.int32)))
        self.workforce[t] = w
        for i in np.flatnonzero(w):
            self._positioning[t, int(i)] = p[i, 0 if w[i] <= 3 else 1].copy()

    def finish(self) -> None:
        """Index the dispatches by step (called once the episode is over)."""
        self.dispatch = {t: (b, f, v) for t, b, f, v in self._dispatch}
        del self._dispatch

    def actions(self, t: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The recorded actions of step ``t`` for the batch rows ``rows`` (in that order)."""
        n = rows.size
        d = np.full((n, self.M), self.N, dtype=np.int64)
        w = self.workforce[t, rows].astype(np.int64)
        p = np.zeros((n, 2, self.M), dtype=np.float64)
        if t in self.dispatch:
            b, f, v = self.dispatch[t]
            where = np.full(self.B, -1, dtype=np.int64)
            where[rows] = np.arange(n)
            keep = where[b] >= 0
            d[where[b[keep]], f[keep]] = v[keep]
        for i in np.flatnonzero(w):
            p[i, 0 if w[i] <= 3 else 1] = self._positioning[t, int(rows[i])]
        return d, w, p


def _module_file(obj: Any) -> str | None:
    module = sys.modules.get(type(obj).__module__)
    path = getattr(module, "__file__", None)
    return os.path.realpath(path) if path and os.path.realpath(path).startswith(str(ROOT)) else None


def _walk(obj: Any, depth: int, ids: list[bytes], files: set[str], seen: set[int]) -> bool:
    """Add ``obj``'s identity to ``ids`` and its module file to ``files``; True if a network decides part of it."""
    if id(obj) in seen or depth > _DEPTH:
        return False
    seen.add(id(obj))
    digest = getattr(obj, "checkpoint_sha256", None)
    if digest is not None:  # a checkpoint's network: what cache.played_key keys it by
        ids.append(f"network:{digest}:{getattr(obj, 'mode', '')}:{getattr(obj, 'seed', '')}:"
                   f"{getattr(obj, 'threads', '')}".encode())
        return True
    path = _module_file(obj)
    if path is not None:
        files.add(path)
    network = False
    ids.append(f"{type(obj).__module__}.{type(obj).__qualname__}".encode())
    for attr, value in sorted(vars(obj).items()) if hasattr(obj, "__dict__") else ():
        if isinstance(value, _PLAIN) or (isinstance(value, tuple) and all(isinstance(v, _PLAIN) for v in value)):
            ids.append(f"{attr}={value!r}".encode())
        elif isinstance(value, np.ndarray) and value.size <= 4096 and value.dtype != object:
            ids.append(attr.encode() + b"=" + np.ascontiguousarray(value).tobytes())
        elif isinstance(value, dict) and attr == "parts":
            for decision, part in sorted(value.items()):
                ids.append(f"part:{decision}".encode())
                network |= _walk(part, depth + 1, ids, files, seen)
        elif hasattr(value, "act") or hasattr(value, "compiled_plan") or hasattr(value, "checkpoint_sha256"):
            ids.append(f"{attr}:".encode())
            network |= _walk(value, depth + 1, ids, files, seen)
        elif attr == "tuned_from" and hasattr(value, "to_dict"):  # the file it was made from, as read
            ids.append(json.dumps(value.to_dict(), sort_keys=True, default=str).encode())
    return network


def identity(policy: Any) -> tuple[list[bytes], set[str], bool]:
    """What decides ``policy``'s actions: identity parts, the source files of its objects, whether a network plays."""
    ids: list[bytes] = []
    files: set[str] = set()
    network = _walk(policy, 0, ids, files, set())
    return ids, files, network


def candidate_key(config: ScenarioConfig, name: str, policy: Any) -> tuple[str, bool]:
    """The key of ``policy``'s (registry name ``name``) episodes on ``config``, and whether it is per seed alone.

    The key covers the compiled code (:func:`wfbench.policies.oracle.cache.code_digest`), the
    source digest of the module of every object of the policy (each with what it imports and
    the numba, numpy and Python versions), the scenario, the name, and the identity
    (:func:`identity`). Per seed alone unless a network plays (then per seed and batch).
    """
    ids, files, network = identity(policy)
    h = hashlib.sha256()
    parts = [cache.code_digest().encode(), cache.scenario_hash(config).encode(), name.encode(), *ids,
             *(source_digest(f).encode() for f in sorted(files))]
    if network:
        torch = sys.modules.get("torch")
        parts.append(str(getattr(torch, "__version__", "")).encode())
    for part in parts:
        h.update(len(part).to_bytes(8, "little") + part)
    return h.hexdigest()[:40], not network


def decisive_files(policy: Any) -> list[str]:
    """The repository paths of every source file whose bytes decide ``policy``'s episodes (sorted).

    The import closure of each of its objects' modules and of the simulator and roll-forward
    (:data:`wfbench.policies.oracle.cache.CODE_FILES`): what :func:`candidate_key` digests. A
    suite piece made at a commit where each of these is byte for byte the same was made by
    this code (:mod:`wfbench.policies.oracle.pieces`).
    """
    _, files, _ = identity(policy)
    files |= {os.path.realpath(PACKAGES[package] / rel) for package, rel in cache.CODE_FILES}
    out = set()
    for f in files:
        out.update(dependencies(f))
    return sorted(os.path.relpath(f, ROOT).replace(os.sep, "/") for f in out)


def entry_keys(seeds: np.ndarray, per_seed: bool) -> np.ndarray:
    """The per-entry keys beside the seed: zeros for a per-seed candidate, the batch's sha256 otherwise."""
    return np.zeros((len(seeds), 1), dtype=np.uint64) if per_seed else cache.batch_keys(seeds)


def _folder(key: str) -> Path | None:
    root = cache.directory()
    return None if root is None else root / (PREFIX + key)


def _file_name(seed: int, keys: np.ndarray) -> str:
    data = np.int64(seed).tobytes() + np.ascontiguousarray(keys, dtype=np.uint64).tobytes()
    return hashlib.sha256(data).hexdigest()[:16] + ".npz"


def lookup(key: str, seeds: np.ndarray, keys: np.ndarray) -> dict[int, Episode]:
    """The stored episodes of ``seeds`` (entry ``keys`` from :func:`entry_keys`), by batch row; missing rows absent."""
    out: dict[int, Episode] = {}
    if not cache.enabled():
        return out
    memo = _MEMORY.setdefault(key, {})
    folder = _folder(key)
    for i, s in enumerate(np.asarray(seeds, dtype=np.int64).tolist()):
        entry = (s, np.ascontiguousarray(keys[i], dtype=np.uint64).tobytes())
        if entry not in memo and folder is not None and (folder / _file_name(s, keys[i])).is_file():
            try:
                with np.load(folder / _file_name(s, keys[i])) as f:
                    if int(f["seed"]) == s and f["keys"].tobytes() == entry[1]:
                        memo[entry] = Episode(float(f["total"]), f["workforce"], f["disp_t"], f["disp_f"], f["disp_v"],
                                              f["pos_t"], f["pos"])
            except (OSError, ValueError, KeyError):  # unreadable: a miss, never a wrong hit
                pass
        if entry in memo:
            out[i] = memo[entry]
    return out


def store(key: str, seed: int, keys: np.ndarray, episode: Episode) -> None:
    """Keep one seed's episode in memory and on disk (nothing when the totals cache is off)."""
    if not cache.enabled():
        return
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    _MEMORY.setdefault(key, {})[(int(seed), keys.tobytes())] = episode
    folder = _folder(key)
    if folder is None:
        return
    tmp = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, suffix=".tmp", delete=False) as f:
            tmp = f.name
            np.savez_compressed(f, seed=np.int64(seed), keys=keys, total=np.float64(episode.total),
                                workforce=episode.workforce, disp_t=episode.disp_t, disp_f=episode.disp_f,
                                disp_v=episode.disp_v, pos_t=episode.pos_t, pos=episode.pos)
        os.replace(tmp, folder / _file_name(int(seed), keys))
    except OSError:  # a read-only or full disk: the memory still holds it
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def clear_memory() -> None:
    """Forget what this process holds in memory (the disk is left as it is)."""
    _MEMORY.clear()


__all__ = ["Episode", "PREFIX", "Recording", "candidate_key", "clear_memory", "decisive_files", "entry_keys",
           "identity", "lookup", "store"]
