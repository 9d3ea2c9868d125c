"""What a second process compiles for the oracle on a cold cache (issue #54, "the first hour").

The oracle's first ``reset`` compiles the every-rule roll-forward (``roll_range`` with the rule
codes at run time), the longest compilation of its first ``evaluate``: on one core it types
every rule's kernel on the way, the dispatch kernels first and the positioning ones last. The
facility-location kernels (:data:`KERNELS`: the p-median of the ``facility`` positioning rules,
dense and sparse, with their solvers) are about a third of it. :func:`oracle_job` hands them to
the second process first, compiled for the types the roll-forward passes them (those of the
kernels' observation tuple, policy state and rows, which ``act_batch`` passes too); the runner
then queues the simulator's step (the roll-forward inlines its workforce kernel, at its end),
and last what the oracle's own ``compile_ahead`` names (the built-in rules its candidates act
with, which its first live ``act`` needs after the roll-forward). This process compiles the
dispatch and workforce rules meanwhile, and when it gets to what the second process compiles
it loads each from disk as soon as it is there (:func:`wfbench.harness.runner.wait_on_miss`).

Once its compilations are done, the second process also plays the oracle's network candidates
(:func:`network_job`): their episodes are the larger part of what is left of a cold first
``evaluate`` after its compilations. It plays them from the last, this process from the first, and
whoever claims a candidate first plays it (:func:`claim`); this process reads the totals the
second one stores in the oracle's totals cache, and waits for one the second process is playing
(:func:`wait_on_totals`), rather than play it again.

It lives beside the oracle, not in it: ``best.py`` is one of the files whose bytes decide the
oracle's committed pieces (``episodes.decisive_files``), and where code is compiled or an episode
is played decides no number: the totals are those ``reset`` would have played, under the same
key, and a winner is played again here for its actions and checked against them.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import typeof, types
from wfbench.policies import kernels as K
from wfbench.policies.kernels.act import act_range
from wfbench.policies.kernels.positioning import positioning_facility, positioning_facility_sparse
from wfbench.policies.oracle import cache as totals_cache
from wfbench.policies.oracle.best import BestInHindsight

from wfbench.core.config import ScenarioConfig
from wfbench.core.observe import allocate_obs

# in the order the roll-forward reaches them (P_FACILITY's branch before P_FACILITY_SPARSE's)
KERNELS = (positioning_facility, positioning_facility_sparse)


def kernel_signature() -> tuple:
    """The argument types the roll-forward and ``act_batch`` call :data:`KERNELS` with.

    ``(b, O, S, hp row, positioning row, t)``: the environment index and the step as int64, the
    kernels' observation tuple and policy state, a row of the (3, ``len(HP_FIELDS)``)
    hyper-parameters and the environment's (2, M) positioning block. Array types do not depend
    on the sizes, so one environment of one facility and one person gives them.
    """
    hp = np.zeros((3, len(K.HP_FIELDS)))
    positioning = np.zeros((1, 2, 1))
    return (types.int64, typeof(allocate_obs(1, 1, 1)), typeof(K.allocate_state(1, 1, 1)), typeof(hp[2]),
            typeof(positioning[0]), types.int64)


def compile_kernels() -> None:
    """Compile (or load) :data:`KERNELS` for :func:`kernel_signature` into numba's on-disk cache."""
    sig = kernel_signature()
    for kernel in KERNELS:
        kernel.compile(sig)


def oracle_job(policy: Any, cached: Callable[[Any], bool]) -> tuple[tuple, tuple] | None:
    """The second process's jobs for a policy with a ``compile_ahead`` hook (the oracles), or None.

    Two ``(what, job, args, waits)``: :func:`compile_kernels` first (``waits``: :data:`KERNELS`),
    and last the hook's own job, the built-in rules the candidates act with (``waits``: their
    ``act_range``), which their first live ``act`` needs after the roll-forward; the runner
    queues the simulator's step between the two. None where the hook has nothing (warm).
    """
    job = policy.compile_ahead(cached)
    if job is None:
        return None
    what, fn, args = job
    return (("the oracle's facility-location kernels", compile_kernels, (), KERNELS),
            (what, fn, args, (act_range,)))


# what this process compiles meanwhile, for the line that announces the jobs: the every-rule roll-forward with
# its rules' kernels, CPU s on an idle 2-core VM (docs/performance.md, "Cold compile": 44 s on 2026-12-02's
# fast morning, 41-48 s at load 1.2-1.8 on 2026-12-03)
HERE = "the oracle's every-rule roll-forward"
HERE_S = 45


# -- the network candidates' episodes, played on the other core --------------------------------------
WAIT_LIMIT_S = 600.0  # the longest this process waits for a total the second process is playing
POLL_S = 0.2  # how often a wait reads the totals cache again


def network_keys(policy: Any) -> dict[str, str]:
    """The oracle's candidates whose totals the totals cache keys by the batch (the networks), by name: their keys.

    Read from the candidates :meth:`BestInHindsight.compile_ahead` resolved for ``reset`` (none
    resolved: none), in the oracle's order; empty where the totals cache is off (nothing could be
    handed back) or the oracle replays pieces (``replay``: its totals come from elsewhere).
    """
    if getattr(policy, "replay", True) or totals_cache.directory() is None:
        return {}
    fresh = getattr(policy, "_fresh", {})  # what compile_ahead resolved, handed to reset unplayed
    keys = {}
    for name in policy.candidates:
        if name in fresh and (key := totals_cache.played_key(policy.config, fresh[name])) is not None:
            keys[name] = key
    return keys


def claim(claims: str, key: str) -> bool:
    """Whether this process is the first to claim the candidate of ``key`` (a file created once, atomically)."""
    try:
        os.close(os.open(os.path.join(claims, key), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    except FileNotFoundError:  # the folder is gone with the job: nobody else plays it
        return True
    return True


def play_networks(config: ScenarioConfig, resolve: Callable[[str], Any], keys: dict[str, str],
                  seeds: Sequence[int], claims: str) -> float:
    """What the second process runs: the network candidates of ``keys`` from the last, each unclaimed one played.

    Each is played to the end on the oracle's batch as its ``reset`` plays it
    (:meth:`BestInHindsight._play_recorded`: the same simulator and calls, no early stop) and its
    totals stored in the totals cache under the key this process computed. It stops at the first
    candidate already claimed (this process got there first; it plays them in the other order),
    or whose key here is not the one ``keys`` holds (nothing stored could be read there).

    Returns:
        The CPU seconds it spent, for the oracle's own cost (:mod:`wfbench.harness.budget`).
    """
    cpu0 = time.process_time()
    seeds = np.asarray(seeds, dtype=np.int64)
    player = BestInHindsight(list(keys), resolve)
    player.attach(config)
    for name, key in reversed(list(keys.items())):
        if not claim(claims, key):
            break
        policy = resolve(name)
        if totals_cache.played_key(config, policy) != key:
            break
        total, _ = player._play_recorded(policy, seeds, np.full(seeds.size, -np.inf))
        totals_cache.store(key, seeds, totals_cache.batch_keys(seeds), total)
    return time.process_time() - cpu0


def wait_on_totals(keys: Sequence[str], claims: str, future: Any, limit_s: float = WAIT_LIMIT_S) -> None:
    """Until ``future`` (:func:`play_networks`) is done, a miss of the totals cache on one of ``keys`` claims or waits.

    The oracle asks the totals cache (``cache.lookup``) for each candidate before it plays it.
    For a network of ``keys`` that it finds no totals of, this claims the candidate for this
    process (it then plays it, as without the second process), or, where the second process
    claimed it first, reads the cache again every ``POLL_S`` until the totals are there, the job
    is done or failed, or ``limit_s`` passed; then the oracle plays what is still missing itself.
    Undone when the job is done, and the claims' folder removed.
    """
    real = totals_cache.__dict__["lookup"]
    watched = set(keys)

    def lookup(key: str, seeds: np.ndarray, entry_keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        total, found = real(key, seeds, entry_keys)
        if future.done():  # its callbacks may run after a reader sees it done: the wait undoes itself too
            undo()
            return total, found
        if key not in watched or found.all() or claim(claims, key):
            return total, found
        deadline = time.monotonic() + limit_s
        while not found.all() and not future.done() and time.monotonic() < deadline:
            try:
                future.result(timeout=min(POLL_S, max(deadline - time.monotonic(), 0.0)))
            except TimeoutError:  # still playing
                pass
            except Exception:  # failed there: play it here
                break
            total, found = real(key, seeds, entry_keys)
        return total, found

    def undo(_: Any = None) -> None:
        if totals_cache.lookup is lookup:
            totals_cache.lookup = real
        shutil.rmtree(claims, ignore_errors=True)

    totals_cache.lookup = lookup
    future.add_done_callback(undo)


def network_jobs(policy: Any, seeds: Sequence[int]) -> tuple | None:
    """The second process's last job for the oracle: its network candidates' episodes; None where it has none.

    ``(what, job, args, start)``: ``start(future)`` makes this process read what the job stores
    (:func:`wait_on_totals`); ``start(None)`` removes the claims where no job was started. Ask
    after :func:`oracle_job` (whose ``compile_ahead`` resolves the candidates). The claims live in
    a fresh folder beside the totals; where it cannot be made (a read-only disk), None: this
    process plays every candidate, as without the job.
    """
    keys = network_keys(policy)
    if not keys:
        return None
    try:
        root = totals_cache.directory() / "claims"
        root.mkdir(parents=True, exist_ok=True)
        claims = tempfile.mkdtemp(prefix=f"{os.getpid()}-", dir=root)
    except OSError:
        return None

    def start(future: Any) -> None:  # None: no second process after all
        if future is None:
            shutil.rmtree(claims, ignore_errors=True)
        else:
            wait_on_totals(list(keys.values()), claims, future)

    return ("playing the oracle's network candidates' episodes (their totals handed back)", play_networks,
            (policy.config, policy.resolve, keys, [int(s) for s in seeds], claims), start)


__all__ = ["HERE", "HERE_S", "KERNELS", "claim", "compile_kernels", "kernel_signature", "network_jobs", "network_keys",
           "oracle_job", "play_networks", "wait_on_totals"]
