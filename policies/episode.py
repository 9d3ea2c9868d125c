"""The episode runner: whole episodes in compiled code for composites of built-in policies.

:func:`play_episodes` resets every environment and runs it to the horizon (observe, act with
the built-in kernels, step), calling the same kernels as ``Simulator.step`` and
``BuiltinDecision.act``, so its results equal stepping the policy through the Python API (a
test checks it). The batch is
split into contiguous ranges, one per thread (``wfbench.core.entrypoints.run_split``), without
changing a bit; the kernel releases the GIL. Why not a ``prange`` loop: ``docs/performance.md``,
"Cold start".
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit
from wfbench.policies.kernels.act import act_codes

from wfbench.core.dynamics import reset_env, step_env
from wfbench.core.entrypoints import bind, run_split
from wfbench.core.observe import observe_env


@njit(cache=True, _nrt=False, nogil=True)  # no reference counting in the episode loop (dynamics.step_env)
def play_range(lo, hi, dc, wc, pc, S, Tr, P, O, PS, hp, dispatch, workforce, positioning):
    """Whole episodes of environments lo..hi-1: reset, then observe, act and step to the horizon.

    ``dc``, ``wc``, ``pc``: the plan's three rule codes, compiled as integer literals
    (``bind(..., literal=CODES)``): one compiled episode per code triple, holding only those
    rules' kernels (:func:`wfbench.policies.kernels.act.act_codes`).
    """
    for b in range(lo, hi):
        reset_env(b, S, Tr, P)
        while S.t[b] < P.horizon:
            observe_env(b, S, P, O, False, False)  # only what the kernels read
            act_codes(dc, wc, pc, b, O, PS, hp, dispatch, workforce, positioning, S.t[b], True)
            step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])


CODES = (2, 3, 4)  # the positions of dc, wc, pc among play_range's arguments: compiled as literals (bind)


def play_parallel(S, Tr, P, O, PS, codes, hp, dispatch, workforce, positioning) -> None:
    """Every episode of the batch on ``numba.get_num_threads()`` threads (the former ``prange`` kernel's call)."""
    _play(codes, numba.get_num_threads(), S, Tr, P, O, PS, hp, dispatch, workforce, positioning)


def _play(codes, threads: int, S, *rest) -> None:
    """:func:`play_range` over the whole batch of ``S`` on ``threads`` ranges, compiled for the rule ``codes``."""
    args = (*(int(c) for c in codes), S, *rest)
    run_split(bind(play_range, 0, 0, *args, literal=CODES), S.t.shape[0], threads, *args)


def play_episodes(sim, codes: np.ndarray, hp: np.ndarray, pstate, threads: int | None = None) -> None:
    """Run every episode of the simulator ``sim`` with a compiled composite's plan.

    ``codes``, ``hp`` and ``pstate`` come from ``Composite.compiled_plan``; ``threads``
    (default: numba's thread count, ``NUMBA_NUM_THREADS``) is capped by that count and
    by the batch size.
    """
    B = sim.B
    dispatch = np.full((B, sim.M), sim.N, dtype=np.int64)
    workforce = np.zeros(B, dtype=np.int64)
    positioning = np.zeros((B, 2, sim.M), dtype=np.float64)
    cap = numba.config.NUMBA_NUM_THREADS
    _play(codes, max(1, min(cap if threads is None else threads, B, cap)), sim.state, sim.trace, sim.params,
          sim.obs_buffers, pstate, hp, dispatch, workforce, positioning)
