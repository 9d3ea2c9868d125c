"""Where episodes run: this process, a pool of processes, or a Ray cluster.

:func:`run_chunks` splits the seeds into chunks, runs each as one batch
(:func:`wfbench.harness.runner.run_batch`) on the chosen backend and yields each
:class:`~wfbench.harness.runner.BatchResult` in completion order; :class:`Execution` is the one
value that says where and how. Every environment's randomness is indexed by its seed, so no
number depends on the backend, the chunking or the order (a test runs all three and compares).
``serial`` is this process, ``process`` loky's reusable pool (no ``__main__`` guard needed; the
policy travels by cloudpickle) and ``ray`` Ray tasks (``address`` joins a cluster, whose nodes
must import the policy's module). ``docs/design.md``, "One Execution value".
"""

from __future__ import annotations

import logging
import math
import os
import socket
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

from joblib.externals.loky import FIRST_COMPLETED, get_reusable_executor, wait
from joblib.externals.loky.backend.utils import kill_process_tree

from wfbench.core.config import ScenarioConfig
from wfbench.harness.guard import LoadedPolicy
from wfbench.harness.runner import BatchResult, prime, run_batch

BACKENDS = ("serial", "process", "ray")
RAY_PROBE_TIMEOUT_S = 5.0  # a HOST:PORT that does not accept a TCP connection in this time has no cluster there
IDLE_WORKER_TIMEOUT_S = 300  # start-up costs seconds per worker; consecutive evaluations reuse them


def check_backend(backend: str, address: str | None = None) -> None:
    """Raise ValueError naming what is allowed unless ``backend`` (and ``address``) can run here."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; available: {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise ValueError(f"address={address!r} only applies to backend 'ray', not {backend!r}")
    if backend == "ray":
        require_ray("backend 'ray'")


@dataclass(frozen=True)
class Execution:
    """Where and how a run's episodes are played: one value, checked once when it is made.

    The orchestrators (:func:`wfbench.evaluate`, :func:`wfbench.tune.tune`,
    :mod:`wfbench.reproduce`) take it as one argument and hand it down unchanged; none of
    these options changes a number (``docs/design.md``, "One Execution value").

    Args:
        backend: ``serial``, ``process`` or ``ray`` (the module docstring).
        workers: processes or Ray tasks of a parallel backend; ``None``: all cores.
        address: the Ray cluster to join (``backend="ray"`` only); ``None``: a local one.
        threads: numba threads of a compiled rollout on ``serial``; ``None``: all cores.
        chunk_size: seeds per batch; ``None``: all seeds on ``serial``, an even split otherwise.
        progress: show a progress bar.

    Raises:
        ValueError: an unknown backend, an address without Ray, a count that is not an
            integer >= 1; one line naming what is allowed.
    """

    backend: str = "serial"
    workers: int | None = None
    address: str | None = None
    threads: int | None = None
    chunk_size: int | None = None
    progress: bool = False

    def __post_init__(self) -> None:
        check_backend(self.backend, self.address)
        for name in ("workers", "threads", "chunk_size"):
            value = getattr(self, name)
            if value is not None and (type(value) is not int or value < 1):
                raise ValueError(f"{name} = {value!r} is not allowed; allowed: None or an integer >= 1")
        if not isinstance(self.progress, bool):
            raise ValueError(f"progress = {self.progress!r} is not allowed; allowed: True or False")

    def replace(self, **changes) -> Execution:
        """A copy with ``changes``, checked again."""
        return replace(self, **changes)


SERIAL = Execution()
"""This process, with numba's threads over all cores: the default of every run."""


def require_ray(what: str) -> None:
    """Raise ValueError saying that ``what`` needs Ray and how to install it, unless Ray imports."""
    try:
        import ray  # noqa: F401 - optional dependency: only its presence is checked here
    except ImportError:
        raise ValueError(f"{what} needs Ray: pip install 'wfbench[ray]'") from None


def split(seeds: Sequence[int], n_chunks: int) -> list[list[int]]:
    size = max(1, math.ceil(len(seeds) / max(1, n_chunks)))
    return [list(seeds[i : i + size]) for i in range(0, len(seeds), size)]


_pool = None  # the reusable executor this process last used, for shutdown_pools


def shutdown_pools(kill_workers: bool = False) -> None:
    """Stop the process pool's workers now (they also stop after being idle, or at interpreter exit).

    Args:
        kill_workers: kill chunks still running instead of waiting for them.
    """
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, kill_workers=kill_workers)
        _pool = None


def check_execution(value: Any, default: Execution | None = None) -> Execution:
    """``value`` as a run's :class:`Execution`: ``default`` for ``None`` where one is given.

    Raises:
        ValueError: anything else, in one line naming what is allowed.
    """
    if value is None and default is not None:
        return default
    if not isinstance(value, Execution):
        allowed = "an Execution or None" if default is not None else "an Execution"
        raise ValueError(f"execution = {value!r} is not allowed; allowed: {allowed}")
    return value


def run_chunks(loaded: LoadedPolicy, config: ScenarioConfig, seeds: Sequence[int], execution: Execution = SERIAL,
               keep_series: bool = False) -> Iterator[BatchResult]:
    """Yield a BatchResult per finished chunk of ``seeds``.

    Args:
        loaded: the policy, resolved once (:func:`wfbench.harness.guard.load_policy`).
        config: the scenario.
        seeds: the seeds to run.
        execution: the backend, its workers or Ray address, the seeds per batch (default all
            seeds for ``serial`` and an even split over the workers otherwise) and the numba
            threads of a compiled rollout on ``serial`` (the parallel backends use one per
            worker); checked when it was made.
        keep_series: keep the per-step metrics.

    Yields:
        Each chunk's result as soon as it is finished.
    """
    backend, workers, address = execution.backend, execution.workers, execution.address
    chunk_size, threads = execution.chunk_size, execution.threads
    seeds = list(seeds)
    by_size = None if chunk_size is None else [seeds[i : i + chunk_size] for i in range(0, len(seeds), chunk_size)]
    if backend == "serial":
        for chunk in by_size or [seeds]:
            yield run_batch(loaded, config, chunk, keep_series, threads)
        return
    workers = workers or os.cpu_count() or 1
    chunks = by_size or split(seeds, workers)
    if backend == "process" and len(chunks) == 1:
        # one chunk gains nothing from a pool but would pay for starting it (each worker imports
        # numpy, numba and wfbench); the numbers do not depend on where a chunk runs
        yield run_batch(loaded, config, chunks[0], keep_series, threads)
        return
    if backend == "process" or not address:  # workers on this machine share its numba cache
        prime(loaded, config)  # compile once here on a cold cache; the workers then load it
    if backend == "process":
        yield from _run_process(loaded, config, chunks, keep_series, workers)
        return
    yield from _run_ray(loaded, config, chunks, keep_series, address)


def _run_process(loaded: LoadedPolicy, config: ScenarioConfig, chunks: list[list[int]], keep_series: bool,
                 workers: int) -> Iterator[BatchResult]:
    global _pool
    pool = _pool = get_reusable_executor(max_workers=workers, timeout=IDLE_WORKER_TIMEOUT_S)
    pending = {pool.submit(run_batch, loaded, config, c, keep_series, 1) for c in chunks}
    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield fut.result()
    finally:
        if pending:  # a chunk failed, or the caller stopped early: the other chunks' results are not wanted
            _abandon(pool)


def _abandon(pool) -> None:
    """Stop ``pool`` now: kill its workers, mid-episode or not, and forget its queued chunks.

    Neither cancelling the futures nor loky's own shutdown would do. A shutdown that
    waits (at the latest the one at interpreter exit) waits for every running chunk to
    finish, minutes on a large scenario after the failure was known. loky 3.6's
    ``shutdown(kill_workers=True)`` fails in its manager thread, which prints
    ``Exception in thread ExecutorManagerThread`` and dies before killing the workers
    (the process then hung at exit on them): with ``InvalidStateError`` when a queued
    future was cancelled, and with ``KeyError`` when more chunks were queued than its
    call queue holds. Killed workers instead take loky's path for a worker that died
    (the pool is marked broken, every future fails, nothing is printed), and the next
    evaluation starts a new pool. The worker processes are ``pool._processes``, not a
    public API; ``tests/contracts/test_failures_one_line.py`` checks that they are killed.
    """
    global _pool
    for process in list(pool._processes.values()):
        try:
            kill_process_tree(process)  # loky's own: SIGKILL (also to a worker's children), then join
        except (OSError, ValueError):  # already gone
            pass
    pool.shutdown(wait=True)  # joins the manager thread, which has seen the workers die
    if _pool is pool:
        _pool = None


class ClusterError(RuntimeError):
    """The Ray cluster an address names cannot be joined; the message is one line naming it and what to check."""


def _probe_authentication(address: str) -> None:
    """One request to the cluster's GCS with this machine's Ray token, so that a refused token is one line at once.

    ``ray.init`` meets a token the cluster refuses with a warning every second for about 20 s and
    then a ``ConnectionError`` that names a stale address. Ray's own GCS client answers the
    same question in a fraction of a second with an ``AuthenticationError``. The client is
    Ray's internal one (``ray._raylet.GcsClient``), so anything other than that error (another
    Ray version's signature, a slow GCS) leaves the question to ``ray.init`` as before.
    """
    import ray.exceptions

    try:
        from ray._raylet import GcsClient

        GcsClient(address=address, cluster_id=None).internal_kv_keys(b"", None, timeout=RAY_PROBE_TIMEOUT_S)
    except ray.exceptions.AuthenticationError as exc:
        first = (str(exc).strip().splitlines() or ["authentication failed"])[0].split(". ")[0]
        raise ClusterError(f"the Ray cluster at {address} refused this machine's authentication token ({first}); "
                           "set RAY_AUTH_TOKEN (or RAY_AUTH_TOKEN_PATH) to the cluster's token, with "
                           "RAY_AUTH_MODE=token") from None
    except Exception:  # noqa: BLE001, S110  (not an answer about the token: ray.init decides, as without the probe)
        pass


def join_ray(address: str, **init_kwargs) -> None:
    """``ray.init(address=...)``, failing fast with one line that names the address and what to check.

    Ray itself, given a ``HOST:PORT`` where nothing listens, retries for minutes and prints a
    warning every few seconds. A ``HOST:PORT`` address is probed first with a plain TCP
    connection (:data:`RAY_PROBE_TIMEOUT_S`), and an error from ``ray.init`` (an
    authentication mismatch, a version mismatch) becomes one line too (:class:`ClusterError`).
    ``"auto"``, ``"local"`` and ``ray://`` addresses go to Ray as they are.
    """
    import ray

    host, colon, port = address.rpartition(":")
    if colon and host and port.isdigit() and "://" not in address:
        try:
            socket.create_connection((host, int(port)), timeout=RAY_PROBE_TIMEOUT_S).close()
        except OSError as exc:
            why = exc.strerror or type(exc).__name__
            raise ClusterError(f"no Ray cluster answers at {address} ({why}); check that `ray start --head --port "
                               f"{port}` runs on {host} and that this machine can reach that port (firewall, the "
                               "address the head prints)") from None
        _probe_authentication(address)
    try:
        ray.init(address=address, **init_kwargs)
    except Exception as exc:  # noqa: BLE001  (Ray's own errors are many classes; the user needs one line)
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ClusterError(f"joining the Ray cluster at {address} failed: {type(exc).__name__}: {first}; check that "
                           "this machine runs the cluster's Ray and Python versions and, where the cluster uses "
                           "token authentication, the same RAY_AUTH_TOKEN") from None


def _run_ray(loaded: LoadedPolicy, config: ScenarioConfig, chunks: list[list[int]], keep_series: bool,
             address: str | None) -> Iterator[BatchResult]:
    import ray  # optional dependency, checked by check_backend

    if not ray.is_initialized():
        if address:
            join_ray(address, ignore_reinit_error=True, log_to_driver=False)
        else:
            # the local cluster we start here: Ray's notice that it turned token authentication on for it is noise
            # on a one-line failure (issue #26); a cluster the user joins (address) keeps all of Ray's messages
            logging.getLogger("ray._private.authentication.authentication_token_setup").setLevel(logging.ERROR)
            # address="local": a new instance of our own, never a cluster that happens to run on this machine
            # (without it ray.init joins the last one started here, and refuses num_cpus for it)
            ray.init(address="local", num_cpus=os.cpu_count() or 1, include_dashboard=False,
                     ignore_reinit_error=True, log_to_driver=False, configure_logging=False)
    task = ray.remote(num_cpus=1)(run_batch)
    pending = [task.remote(loaded, config, c, keep_series, 1) for c in chunks]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayTaskError as exc:
                    # Ray wraps the task's exception with the remote traceback in its message; the
                    # exception itself (a PolicyError with its one line and trace) is what callers handle
                    raise exc.cause from None
    finally:
        for ref in pending:
            ray.cancel(ref)
        # a chunk that had already failed too holds an error nobody read: Ray prints it with its traceback
        # ("Unhandled error") when the reference is dropped, which broke the one-line failure on a loaded
        # machine (a second chunk failing before the cancel); reading it marks it handled
        for ref in pending:
            try:
                ray.get(ref, timeout=10)
            except Exception:  # noqa: BLE001  (cancelled or failed: the first failure is the one reported)
                pass
