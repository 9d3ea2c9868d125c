"""Exact look-ahead: copy a simulator's state and roll the copy forward.

Every exogenous draw is indexed by what it is for, not when it is asked for (``docs/design.md``,
"The trace and common random numbers"), so a copy of an environment's state stepped with the
same actions follows the original bit for bit. :func:`fork` makes a new
:class:`~wfbench.core.simulator.Simulator` of copies of chosen environments (deep copies: stepping
one never changes the other); :func:`copy_state` refreshes a fork in place without allocating;
:func:`state_equal` compares two states array by array. The hindsight oracles score candidate
actions this way (``docs/hindsight.md``, "Exact look-ahead").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from wfbench.core.simulator import Simulator
from wfbench.core.state import State


def fork_index(B: int, envs: int | Sequence[int] | None = None, copies: int = 1) -> np.ndarray:
    """Source row of each row of a fork: every env of ``envs`` (all when None) repeated ``copies`` times.

    Rows are grouped by source environment: row ``i * copies + k`` is copy k of ``envs[i]``.

    Raises:
        ValueError: an environment index out of range, or ``copies < 1``.
    """
    if type(copies) is not int or copies < 1:
        raise ValueError(f"copies = {copies!r} is not allowed; allowed: an integer >= 1")
    if envs is None:
        idx = np.arange(B, dtype=np.int64)
    else:
        idx = np.atleast_1d(np.asarray(envs, dtype=np.int64))
        if idx.ndim != 1 or idx.size == 0 or (idx < 0).any() or (idx >= B).any():
            raise ValueError(f"envs = {envs!r} is not allowed; allowed: indices 0..{B - 1} of the batch")
    return np.repeat(idx, copies)


def fork(sim: Simulator, envs: int | Sequence[int] | None = None, copies: int = 1,
         keep_series: bool = False, threads: int | None = 1) -> Simulator:
    """A new simulator holding ``copies`` copies of each of ``envs`` of ``sim``, at ``sim``'s step.

    Args:
        sim: a simulator that has been reset.
        envs: the environments to copy (an index or a sequence); all of them when None.
        copies: copies of each (rows grouped by source, see :func:`fork_index`).
        keep_series: keep per-step metrics in the fork (the source's past steps are
            copied too); off by default, since a look-ahead needs only the totals.
        threads: threads of the fork's ``step``/``observe`` (1 by default: a planner
            usually runs one fork per process).

    Returns:
        A simulator with ``len(envs) * copies`` environments, each in exactly the state
        of its source, with the same seeds and the same trace rows.

    Raises:
        RuntimeError: ``sim`` was not reset.
    """
    if not getattr(sim, "_reset_done", False):
        raise RuntimeError("fork() needs a simulator that has been reset")
    idx = fork_index(sim.B, envs, copies)
    out = Simulator(sim.config, [int(s) for s in sim.seeds[idx]], keep_series=keep_series, threads=threads)
    out.reset()  # an ordinary, stepped-ready simulator; its state is overwritten just below
    # the same trace rows as the source (the trace is a pure function of (config, seed): only the padding of
    # the arrival lists may differ, which no rule reads; sharing the rows makes the fork's inputs the source's)
    out.trace = type(sim.trace)(*(np.ascontiguousarray(a[idx]) for a in sim.trace))
    copy_state(out, sim, idx)
    return out


def copy_state(dst: Simulator, src: Simulator, index: np.ndarray) -> None:
    """Make environment i of ``dst`` a copy of environment ``index[i]`` of ``src``: state, trace rows, seed.

    ``dst`` must come from :func:`fork` of ``src`` (same scenario, same padding of the
    arrival lists). It keeps its array objects (and so its compiled entry points); row i
    of every state and trace array becomes a copy of row ``index[i]`` of ``src``'s, for i below ``len(index)``
    (``index`` may be shorter than ``dst``'s batch: the rows after it are left as they
    are). The per-step series is copied only when ``dst`` keeps one.

    Raises:
        ValueError: the shapes do not match (a different scenario, or more rows than ``dst`` has).
    """
    index = np.asarray(index, dtype=np.int64)
    n = index.shape[0] if index.ndim == 1 else -1
    if not 0 < n <= dst.B:
        raise ValueError(f"index has shape {index.shape}; allowed: 1..{dst.B} rows (the fork's environments)")
    for name, d, s in zip(State._fields, dst.state, src.state, strict=True):
        if name == "series" and d.shape[1] == 0:
            continue
        if d.shape[1:] != s.shape[1:]:
            raise ValueError(f"state field {name}: fork rows {d.shape[1:]} differ from source rows {s.shape[1:]}")
        np.take(s, index, axis=0, out=d[:n])
    for name, d, s in zip(type(src.trace)._fields, dst.trace, src.trace, strict=True):
        if d.shape[1:] != s.shape[1:]:
            raise ValueError(f"trace field {name}: fork rows {d.shape[1:]} differ from source rows {s.shape[1:]}; "
                             "make the fork with fork(src)")
        np.take(s, index, axis=0, out=d[:n])
    dst.seeds[:n] = src.seeds[index]


def state_equal(a: Simulator, b: Simulator, rows_a=None, rows_b=None, series: bool = False) -> list[str]:
    """The names of the state arrays that differ between ``a`` and ``b`` (empty: bit-identical).

    ``rows_a``/``rows_b`` select environments of each (all when None). The per-step
    series is compared only when ``series`` is True. Floats are compared bit for bit
    (NaN equals NaN of the same bits).
    """
    differ = []
    for name, x, y in zip(State._fields, a.state, b.state, strict=True):
        if name == "series" and not series:
            continue
        x = x if rows_a is None else x[rows_a]
        y = y if rows_b is None else y[rows_b]
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            differ.append(name)
    return differ
