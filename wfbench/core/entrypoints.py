"""Calling the compiled core fast: entry points bound to argument types, and a thread pool over ranges of a batch.

:func:`bind` skips numba's per-call type resolution (about 13 us for the state, trace,
parameter and observation tuples, against about 1 us for the call itself);
:func:`run_split` spreads a range kernel over contiguous ranges of environments in a
shared thread pool. Environments are independent, so neither changes a bit of a result
(docs/performance.md).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba.core import types


def _fingerprint(x):
    """What numba's type of an argument depends on, cheap to compute and hashable.

    Arrays: dtype, ndim, contiguity, writeable, aligned (numba's layout, readonly and
    aligned attributes); tuples: their class and members; Python ints: whether they fit
    int64 (numba types larger ones otherwise); any other value: its Python type.
    """
    if isinstance(x, np.ndarray):
        f = x.flags
        return (type(x), x.dtype.str, x.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if isinstance(x, tuple):
        return (type(x), tuple(_fingerprint(v) for v in x))
    if type(x) is int:
        return (int, -(2**63) <= x < 2**63)
    return type(x)


_ENTRY_POINTS: dict = {}  # (dispatcher, fingerprint of the arguments) -> entry point


def bind(dispatcher, *args, literal: tuple[int, ...] = ()):
    """The compiled entry point of a numba ``dispatcher`` for the types of ``args``.

    ``literal``: the positions of integer arguments compiled as literals, their values part of
    the signature (one compiled entry point per value: the compiled episode per rule codes).

    Calling a dispatcher resolves the numba type of every argument first; for the state,
    trace, parameter and observation tuples (about 80 arrays and scalars) that costs
    ~13 us, against ~1 us for the call itself. The entry point skips the resolution, so
    it must only ever get arguments of exactly these types: ``Simulator.call`` (and the
    simulator's own steps) bind it to the simulator's own tuples and passes actions that :func:`validate_actions` made
    plain (C-contiguous, aligned, writeable int64 and float64 arrays).
    """
    key = (dispatcher, _fingerprint(args), tuple(int(args[i]) for i in literal))
    entry = _ENTRY_POINTS.get(key)
    if entry is None:
        # numba's typeof of the namedtuples takes ~1 ms; the fingerprint ~0.05 ms
        entry = _ENTRY_POINTS[key] = dispatcher.compile(tuple(
            types.literal(int(a)) if i in literal else dispatcher.typeof_pyval(a) for i, a in enumerate(args)))
    return entry


_POOL: list = [None, 0, 0]  # [ThreadPoolExecutor, its number of threads, the pid that made it]
_POOL_LOCK = threading.Lock()


def _thread_pool(workers: int) -> ThreadPoolExecutor:
    """A pool of at least ``workers`` threads, kept for the life of the process (remade after a fork).

    A larger pool replaces a smaller one without shutting it down (a caller in another
    thread may still be using it); its idle threads exit when it is garbage collected.
    """
    with _POOL_LOCK:
        pool, size, pid = _POOL
        if pool is None or size < workers or pid != os.getpid():
            pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="wfbench")
            _POOL[:] = [pool, workers, os.getpid()]
        return pool


def run_split(entry, B: int, threads: int, *args) -> None:
    """Call ``entry(lo, hi, *args)`` on ``threads`` contiguous ranges that cover environments 0..B-1.

    ``entry`` is a compiled range kernel that releases the GIL (``nogil=True``); the
    first range runs in the calling thread, the others in a shared thread pool, and
    this returns when all have finished (re-raising the first error). The ranges are
    numba's static ``prange`` schedule: sizes differing by at most one. Environments
    are independent, so the results do not depend on ``threads``.
    """
    n = max(1, min(threads, B))
    if n == 1:
        entry(0, B, *args)
        return
    bounds = [B * i // n for i in range(n + 1)]
    futures = [_thread_pool(n - 1).submit(entry, bounds[i], bounds[i + 1], *args) for i in range(1, n)]
    try:
        entry(bounds[0], bounds[1], *args)
    finally:
        for f in futures:
            f.result()
