"""Whole episodes in compiled code for composites of built-in policies.

``rollout`` resets every environment and runs it to the horizon: observe, act with
the built-in kernels, step. It calls the same kernels as ``Simulator.step`` and
``BuiltinDecision.act``, so its results are identical to stepping the policy through
the Python API (a test checks this); it only removes the per-step Python overhead.
Environments are independent, so ``prange`` spreads them over cores without changing a
bit of any result; with one numba thread it is a serial loop (there is no separate
serial kernel: the whole-episode kernel is the slowest thing to compile).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from policies.kernels import act_env
from wfbench.dynamics import reset_env, step_env
from wfbench.observe import observe_env


@njit(cache=True, _nrt=False)  # no reference counting in the episode loop (see wfbench.dynamics.step_env)
def _run_env(b, S, Tr, P, O, PS, codes, hp, dispatch, workforce, positioning):
    reset_env(b, S, Tr, P)
    while S.t[b] < P.horizon:
        observe_env(b, S, P, O, False, False)  # only what the kernels read
        act_env(b, O, PS, codes, hp, dispatch, workforce, positioning, S.t[b], True)
        step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])


@njit(cache=True, parallel=True)
def rollout_parallel(S, Tr, P, O, PS, codes, hp, dispatch, workforce, positioning):
    for b in prange(S.t.shape[0]):
        _run_env(b, S, Tr, P, O, PS, codes, hp, dispatch, workforce, positioning)


def rollout(sim, codes: np.ndarray, hp: np.ndarray, pstate, threads: int | None = None) -> None:
    """Run every episode of the simulator ``sim`` with a compiled composite's plan.

    ``codes``, ``hp`` and ``pstate`` come from ``Composite.compiled_plan``; ``threads``
    (default: all of numba's) is capped by the batch size. One compiled rollout serves
    every thread count (one thread: a serial loop), so the large whole-episode kernel is
    compiled once, not twice.
    """
    B = sim.B
    dispatch = np.full((B, sim.M), sim.N, dtype=np.int64)
    workforce = np.zeros(B, dtype=np.int64)
    positioning = np.zeros((B, 2, sim.M), dtype=np.float64)
    cap = numba.config.NUMBA_NUM_THREADS
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(cap if threads is None else threads, B, cap)))
    try:
        rollout_parallel(sim.state, sim.trace, sim.params, sim.obs_buffers, pstate, codes, hp, dispatch, workforce,
                         positioning)
    finally:
        numba.set_num_threads(previous)
