"""Where episodes run: this process, a pool of processes, or a Ray cluster.

:func:`run_chunks` splits the seeds into chunks, runs each chunk as one batch
(:func:`wfbench.evaluate.run_batch`) on the chosen backend and yields each
:class:`~wfbench.evaluate.BatchResult` as soon as it is finished, in completion order.
Every environment is independent and all its randomness is indexed by its seed, so
the numbers for a seed do not depend on the backend, the chunking or the order (a
test runs all three backends and compares).

- ``serial``: this process; a chunk of built-in compiled policies uses all cores
  through numba threads.
- ``process``: a pool of ``workers`` processes (spawned: no state leaks in).
- ``ray``: Ray tasks. ``address`` joins an existing cluster (``"auto"`` or
  ``"ray://host:10001"``); without it a local Ray instance is started. The policy is
  sent by its spec (a registry name or ``module:attr``), which every node must be
  able to import.
"""

from __future__ import annotations

import atexit
import math
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import get_context
from typing import Any

from wfbench.config import ScenarioConfig

BACKENDS = ("serial", "process", "ray")


def check_backend(backend: str, address: str | None = None) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; available: {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise ValueError(f"address={address!r} only applies to backend 'ray', not {backend!r}")
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError("backend 'ray' needs Ray: pip install 'wfbench[ray]'") from None


def split(seeds: Sequence[int], n_chunks: int) -> list[list[int]]:
    size = max(1, math.ceil(len(seeds) / max(1, n_chunks)))
    return [list(seeds[i : i + size]) for i in range(0, len(seeds), size)]


_POOLS: dict[int, ProcessPoolExecutor] = {}


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A spawned pool of ``workers`` processes, kept for the life of this process.

    Start-up (imports, loading the compiled code) costs about a second per worker, so
    consecutive evaluations (the rows of a table) share one pool.
    """
    pool = _POOLS.get(workers)
    if pool is None:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"))
        _POOLS[workers] = pool
        atexit.register(pool.shutdown, cancel_futures=True)
    return pool


def shutdown_pools() -> None:
    """Stop the shared worker pools now (they also stop at interpreter exit)."""
    while _POOLS:
        _, pool = _POOLS.popitem()
        pool.shutdown(wait=True, cancel_futures=True)


def _run_chunk(args: tuple) -> Any:
    from wfbench.evaluate import run_batch

    policy, config, seeds, keep_series, threads = args
    return run_batch(policy, config, seeds, keep_series=keep_series, threads=threads)


def run_chunks(policy: Any, config: ScenarioConfig, seeds: Sequence[int], backend: str = "serial",
               workers: int | None = None, address: str | None = None, chunk_size: int | None = None,
               keep_series: bool = False, threads: int | None = None) -> Iterator[Any]:
    """Yield a BatchResult per finished chunk of ``seeds``.

    ``policy`` must be a spec (a string) for the ``process`` and ``ray`` backends unless
    the object pickles. ``chunk_size`` defaults to all seeds for ``serial`` and to an
    even split over the workers otherwise.
    """
    check_backend(backend, address)
    seeds = list(seeds)
    by_size = None if chunk_size is None else [seeds[i : i + chunk_size] for i in range(0, len(seeds), chunk_size)]
    if backend == "serial":
        for chunk in by_size or [seeds]:
            yield _run_chunk((policy, config, chunk, keep_series, threads))
        return
    workers = workers or os.cpu_count() or 1
    chunks = by_size or split(seeds, workers)
    if backend == "process" and len(chunks) == 1:
        # one chunk gains nothing from a pool but would pay for spawning it (~2 s of start-up:
        # each worker imports numpy, numba and wfbench); the numbers do not depend on where
        # a chunk runs
        yield _run_chunk((policy, config, chunks[0], keep_series, threads))
        return
    if backend == "process":
        pool = process_pool(workers)
        pending = {pool.submit(_run_chunk, (policy, config, c, keep_series, 1)) for c in chunks}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
        finally:
            for fut in pending:
                fut.cancel()
        return
    yield from _run_ray(policy, config, chunks, keep_series, address)


def _run_ray(policy: Any, config: ScenarioConfig, chunks: list[list[int]], keep_series: bool,
             address: str | None) -> Iterator[Any]:
    import ray

    if not ray.is_initialized():
        if address:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
        else:
            ray.init(num_cpus=os.cpu_count() or 1, include_dashboard=False, ignore_reinit_error=True,
                     log_to_driver=False, configure_logging=False)
    task = ray.remote(num_cpus=1)(_run_chunk)
    pending = [task.remote((policy, config, c, keep_series, 1)) for c in chunks]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        for ref in done:
            yield ray.get(ref)
