"""Episode totals of compiled composites and shipped networks, shared by the evaluation runner and the ``oracle``.

A total (``sim.state.totals[:, K_NSW]``, float64) is keyed by everything it depends on: the
compiled code (:func:`code_digest`), the scenario (:func:`scenario_hash`), the policy's
``compiled_plan`` and the seed's random keys, and the seed; a network's (:func:`played_key`)
also by the batch's seeds in order (:func:`batch_keys`), since its sampled actions can change
with the batch in the last float bit. So a hit is the total the play would give, bit for bit.
:func:`lookup` and :func:`store` use memory and ``.npz`` files in ``$WFBENCH_ORACLE_CACHE``
(``off`` turns it off), else ``$WFBENCH_CACHE_DIR/oracle-totals``, else the user cache folder.
Every part of the key, who writes and the file layout: ``docs/hindsight.md``, "Episodes played once".
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from wfbench.policies.builtin import BuiltinDecision

from wfbench.core.config import ScenarioConfig
from wfbench.core.jit import ENV_CACHE_DIR, PACKAGES, source_digest

ENV = "WFBENCH_ORACLE_CACHE"
OFF = ("off", "0", "false", "no", "")
# the episode runner, the roll-forward and the simulator that makes the trace and resets: (package, file)
CODE_FILES = (("wfbench.policies", "episode.py"), ("wfbench.policies", "kernels/forward.py"),
              ("wfbench", "core/simulator.py"))

_MEMORY: dict[str, dict[tuple[int, bytes], float]] = {}  # key -> (seed, keys bytes) -> total
_CODE: list[str] = []


def enabled() -> bool:
    """False when ``WFBENCH_ORACLE_CACHE`` says off."""
    value = os.environ.get(ENV)
    return value is None or value.strip().lower() not in OFF


def directory() -> Path | None:
    """The on-disk store (None when the cache is off)."""
    if not enabled():
        return None
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    if os.environ.get(ENV_CACHE_DIR):
        return Path(os.environ[ENV_CACHE_DIR]) / "oracle-totals"
    import platformdirs

    return Path(platformdirs.user_cache_dir("wfbench", appauthor=False)) / "oracle-totals"


def code_digest() -> str:
    """sha256 of the source digests of :data:`CODE_FILES` (computed once per process)."""
    if not _CODE:
        h = hashlib.sha256()
        for package, rel in CODE_FILES:
            h.update(f"{package}/{rel}".encode() + b"\0" + source_digest(PACKAGES[package] / rel).encode() + b"\0")
        _CODE.append(h.hexdigest())
    return _CODE[0]


def scenario_hash(config: ScenarioConfig) -> str:
    """sha256 of the scenario's canonical JSON."""
    text = json.dumps(config.to_dict(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def policy_key(config: ScenarioConfig, codes: np.ndarray, hp: np.ndarray) -> str:
    """The key of a compiled policy's totals on ``config``: the code, the scenario, the codes and hyper-parameters."""
    h = hashlib.sha256()
    for part in (code_digest().encode(), scenario_hash(config).encode(),
                 np.ascontiguousarray(codes, dtype=np.int64).tobytes(),
                 np.ascontiguousarray(hp, dtype=np.float64).tobytes()):
        h.update(len(part).to_bytes(8, "little") + part)
    return h.hexdigest()[:40]


def _entries(seeds: np.ndarray, keys: np.ndarray) -> list[tuple[int, bytes]]:
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    return [(int(s), keys[i].tobytes()) for i, s in enumerate(seeds)]


def _load(key: str) -> dict[tuple[int, bytes], float]:
    """The memory entries of ``key``, merged with what the disk holds for it."""
    memo = _MEMORY.setdefault(key, {})
    folder = directory()
    if folder is None or not (folder / key).is_dir():
        return memo
    for path in (folder / key).glob("*.npz"):
        try:
            with np.load(path) as f:
                seeds, keys, totals = f["seeds"], f["keys"], f["totals"]
        except (OSError, ValueError, KeyError):  # unreadable: a miss, never a wrong hit
            continue
        for entry, total in zip(_entries(seeds, keys), totals.tolist(), strict=True):
            memo.setdefault(entry, total)
    return memo


def lookup(key: str, seeds: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The stored totals of ``seeds`` (with their random ``keys``, (B, 3)): (totals, found), NaN where not found."""
    seeds = np.asarray(seeds, dtype=np.int64)
    totals = np.full(seeds.size, np.nan)
    found = np.zeros(seeds.size, dtype=bool)
    if not enabled():
        return totals, found
    entries = _entries(seeds, keys)
    memo = _MEMORY.get(key, {})
    if not all(e in memo for e in entries):
        memo = _load(key)
    for i, e in enumerate(entries):
        if e in memo:
            totals[i], found[i] = memo[e], True
    return totals, found


def store(key: str, seeds: np.ndarray, keys: np.ndarray, totals: np.ndarray) -> None:
    """Keep the episode totals of ``seeds`` (random ``keys`` before the episode) in memory and on disk."""
    if not enabled():
        return
    seeds = np.asarray(seeds, dtype=np.int64)
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    totals = np.asarray(totals, dtype=np.float64)
    memo = _MEMORY.setdefault(key, {})
    new = []
    for i, (e, total) in enumerate(zip(_entries(seeds, keys), totals.tolist(), strict=True)):
        if e not in memo:
            memo[e] = total
            new.append(i)
    folder = directory()
    if not new or folder is None:
        return
    rows = np.array(new)
    name = hashlib.sha256(seeds[rows].tobytes() + keys[rows].tobytes()).hexdigest()[:16] + ".npz"
    tmp = None
    try:
        (folder / key).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder / key, suffix=".tmp", delete=False) as f:
            tmp = f.name
            np.savez(f, seeds=seeds[rows], keys=keys[rows], totals=totals[rows])
        os.replace(tmp, folder / key / name)
    except OSError:  # a read-only or full disk: the memory still holds them
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


# -- episodes played through act: a checkpoint's network ------------------------------------------------
# the network's sampling and the composite around it: (package, file), each with what it imports
PLAYED_CODE_FILES = (("wfbench.policies", "neural/policy.py"),)


def _part_identity(part: Any) -> bytes | None:
    """What decides one part's actions, or None when this module cannot tell (then nothing is cached)."""
    digest = getattr(part, "checkpoint_sha256", None)
    if digest is not None:  # a checkpoint's network (wfbench.policies.neural.policy.from_checkpoint)
        return f"network:{digest}:{part.mode}:{part.seed}:{part.threads}".encode()
    if isinstance(part, BuiltinDecision):  # a built-in kernel: its code, hyper-parameters and seed
        return f"kernel:{part.code}:{part.seed}:".encode() + np.ascontiguousarray(part.hp, dtype=np.float64).tobytes()
    return None


def played_key(config: ScenarioConfig, policy: Any) -> str | None:
    """The key of the totals of a checkpoint's network (alone, or in a composite beside built-in kernels).

    Such a policy plays the same episode on a seed given the same batch, but the batch
    can move its sampled actions in the last float bit (batched matrix products), so its
    totals are stored per seed *and batch* (:func:`batch_keys`). The key covers the
    code (:func:`code_digest` and :data:`PLAYED_CODE_FILES`), torch's version, the
    scenario, and per decision the checkpoint's sha256, mode, seed and torch threads, or
    the kernel's code, hyper-parameters and seed. None for any other policy.
    """
    parts = getattr(policy, "parts", None)
    parts = parts if isinstance(parts, dict) else {"all": policy}  # a composite's, or the policy alone
    if all(getattr(p, "checkpoint_sha256", None) is None for p in parts.values()):
        return None  # no network: kernels alone run compiled, keyed by policy_key
    ids = []
    for decision, part in sorted(parts.items()):
        ident = _part_identity(part)
        if ident is None:
            return None
        ids.append(decision.encode() + b"=" + ident)
    torch = sys.modules.get("torch")  # a checkpoint's policy has imported it
    h = hashlib.sha256()
    code = [source_digest(PACKAGES[package] / rel).encode() for package, rel in PLAYED_CODE_FILES]
    for part in (code_digest().encode(), *code, str(getattr(torch, "__version__", "")).encode(),
                 scenario_hash(config).encode(), *ids):
        h.update(len(part).to_bytes(8, "little") + part)
    return "played-" + h.hexdigest()[:40]


def batch_keys(seeds: np.ndarray) -> np.ndarray:
    """(B, 4) uint64: each row the sha256 of the whole batch's seeds, in order (the per-seed keys of a played total)."""
    digest = hashlib.sha256(np.ascontiguousarray(seeds, dtype=np.int64).tobytes()).digest()
    return np.tile(np.frombuffer(digest, dtype=np.uint64), (len(seeds), 1))


def clear_memory() -> None:
    """Forget what this process holds in memory (the disk is left as it is)."""
    _MEMORY.clear()


__all__ = ["ENV", "batch_keys", "clear_memory", "code_digest", "directory", "enabled", "lookup", "played_key",
           "policy_key", "scenario_hash", "store"]
