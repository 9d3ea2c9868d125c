"""The roll-forward: step a batch from its current state under the built-in kernels, compiled.

The oracles (:mod:`wfbench.policies.oracle`) and the deployable lookaheads
(:mod:`wfbench.policies.lookahead`) both score with it. :func:`roll_forward` is
:func:`wfbench.policies.episode.play_episodes` without the reset and for a number of steps,
usually on a fork (:func:`wfbench.core.fork.fork`), with an optional explicit first action.
It calls the same ``step_env``, ``observe_env`` and rule kernels (``act_codes``) as
``Simulator.step``, so it plays the episode the simulator would (tested). A lookahead, whose
futures are played by one base, compiles it for that base's rules only (``literal=True``); the
oracle, which rolls many composites in one process, compiles it once for every rule. It returns the sum of ``NSW_t`` per
environment and can record where requests open (the known future demand)
(``docs/hindsight.md``, "Exact look-ahead").
"""

from __future__ import annotations

import numpy as np
from numba import njit
from wfbench.policies.kernels.act import act_codes

from wfbench.core.dynamics import step_env
from wfbench.core.entrypoints import bind
from wfbench.core.observe import observe_env


@njit(cache=True, inline="always")
def _record_onsets(b, S, seen, onset_xy, n_onsets):
    """Append the cell of every request opened since ``seen`` (each slot's request index) to ``onset_xy[b]``."""
    M = S.fac_active.shape[1]
    cap = onset_xy.shape[1]
    for f in range(M):
        r = S.fac_request[b, f]
        if r != seen[b, f]:
            seen[b, f] = r
            if S.fac_active[b, f] and S.fac_down[b, f]:
                k = n_onsets[b]
                if k < cap:
                    onset_xy[b, k, 0] = S.fac_x[b, f]
                    onset_xy[b, k, 1] = S.fac_y[b, f]
                n_onsets[b] = k + 1


@njit(cache=True, _nrt=False, nogil=True)  # no reference counting in the loop (see wfbench.core.dynamics.step_env)
def roll_range(lo, hi, dc, wc, pc, S, Tr, P, O, PS, hp, dispatch, workforce, positioning, first, first_d, first_w,
               first_p, steps, record, seen, onset_xy, n_onsets, score, lazy):
    """Roll environments lo..hi-1 forward ``steps`` steps (capped by the horizon).

    With ``first``, the first step takes the explicit actions ``first_d[b]``,
    ``first_w[b]``, ``first_p[b]``; every other step observes (the parts the kernels
    read) and acts with the kernels of the rule codes ``dc``, ``wc``, ``pc`` (integer literals
    of the compilation, or plain integers: :func:`wfbench.policies.kernels.act.act_codes`).
    ``score[b]`` gets the sum of NSW over the steps run. With ``record``, the cells of the
    requests that open are appended to ``onset_xy[b]`` (``n_onsets[b]`` counts them, also past
    the capacity). ``lazy`` is True (:func:`roll_forward`); an argument, not a constant, so that
    the rules' compilation is the one ``Policy.act``'s ``act_range`` made (same types and
    flags: numba compiles an overload's body again for a caller that differs in either).
    """
    for b in range(lo, hi):
        end = min(S.t[b] + steps, P.horizon)
        total = 0.0
        if record:
            n_onsets[b] = 0
            for f in range(S.fac_active.shape[1]):
                seen[b, f] = S.fac_request[b, f]
        explicit = first  # the first step's actions are given
        while S.t[b] < end:  # one call of the (inlined) step: compiled once, not once per kind of step
            if explicit:
                d, w, p = first_d[b], first_w[b], first_p[b]
                explicit = False
            else:
                observe_env(b, S, P, O, False, False)  # only what the kernels read
                act_codes(dc, wc, pc, b, O, PS, hp, dispatch, workforce, positioning, S.t[b], lazy)
                d, w, p = dispatch[b], workforce[b], positioning[b]
            total += step_env(b, S, Tr, P, d, w, p)
            if record:
                _record_onsets(b, S, seen, onset_xy, n_onsets)
        score[b] = total


class RollBuffers:
    """Scratch arrays of :func:`roll_forward` for a batch of B environments (reused call to call)."""

    def __init__(self, B: int, M: int, N: int, onset_capacity: int = 1024):
        self.dispatch = np.full((B, M), N, dtype=np.int64)
        self.workforce = np.zeros(B, dtype=np.int64)
        self.positioning = np.zeros((B, 2, M), dtype=np.float64)
        self.first_d = np.full((B, M), N, dtype=np.int64)
        self.first_w = np.zeros(B, dtype=np.int64)
        self.first_p = np.zeros((B, 2, M), dtype=np.float64)
        self.seen = np.zeros((B, M), dtype=np.int64)
        self.onset_xy = np.zeros((B, onset_capacity, 2), dtype=np.int64)
        self.n_onsets = np.zeros(B, dtype=np.int64)
        self.score = np.zeros(B, dtype=np.float64)


CODES = (2, 3, 4)  # the positions of dc, wc, pc among roll_range's arguments: literals where a base is fixed (bind)


def roll_forward(sim, steps: int, codes: np.ndarray, hp: np.ndarray, pstate, first: bool = False,
                 buffers: RollBuffers | None = None, record: bool = False, rows: int | None = None,
                 literal: bool = False) -> np.ndarray:
    """Roll every environment of ``sim`` forward ``steps`` steps under the built-in kernels ``codes``.

    Args:
        sim: a reset :class:`~wfbench.core.simulator.Simulator` (typically a fork); its
            state advances in place.
        steps: steps to run (fewer where the horizon comes first).
        codes: the kernel codes (dispatch, workforce, positioning), int64 (3,), as in
            ``Composite.compiled_plan``.
        hp: the (3, ``len(HP_FIELDS)``) hyper-parameters.
        pstate: the kernels' :class:`~wfbench.policies.kernels.PolicyState` with B rows (advances in place).
        first: take ``buffers.first_d``, ``first_w``, ``first_p`` as the first step's actions.
        buffers: scratch arrays (:class:`RollBuffers` of B rows); made when None.
        record: record the cells of the requests that open (``buffers.onset_xy``, ``n_onsets``).
        rows: roll only environments 0..rows-1 (all when None); the others stay as they are.
        literal: compile the roll-forward for these ``codes`` only (a lookahead's one base: its
            first call compiles that base's rules alone); otherwise one compilation serves
            every rule (the oracle's candidates). The episodes are the same either way.

    Returns:
        (B,) float64: the sum of NSW_t over the steps run (a view of ``buffers.score``).
    """
    if buffers is None:
        buffers = RollBuffers(sim.B, sim.M, sim.N)
    args = (*(int(c) for c in codes), sim.state, sim.trace, sim.params, sim.obs_buffers, pstate,
            np.ascontiguousarray(hp, dtype=np.float64), buffers.dispatch, buffers.workforce, buffers.positioning,
            bool(first), buffers.first_d, buffers.first_w, buffers.first_p, int(steps), bool(record), buffers.seen,
            buffers.onset_xy, buffers.n_onsets, buffers.score, True)
    bind(roll_range, 0, 0, *args, literal=CODES if literal else ())(0, sim.B if rows is None else int(rows), *args)
    return buffers.score


def roll_candidates(sim, steps: int, codes: np.ndarray, hp: np.ndarray, pstate, fork_pstate, buffers: RollBuffers,
                    env_rows: np.ndarray, first_w, d: np.ndarray, p: np.ndarray, literal: bool = False) -> np.ndarray:
    """Score candidate workforce actions: :func:`roll_forward` of rows 0..n-1 of ``sim``, each from its environment.

    Row i (its world already written into ``sim``) starts from the kernel state ``pstate`` of
    environment ``env_rows[i]``, copied into ``fork_pstate``, and takes that environment's
    dispatch ``d`` and positioning ``p`` with the workforce action ``first_w[i]`` as its first
    step (``literal``: as :func:`roll_forward`'s). Returns the (n,) sums of NSW over the steps
    run. The rollout's and the hindsight rollout's decisions
    (:mod:`wfbench.policies.lookahead.rollout`, :mod:`wfbench.policies.oracle.hindsight`) both
    score this way.
    """
    n = len(env_rows)
    for src, dst in zip(pstate, fork_pstate, strict=True):
        np.take(src, env_rows, axis=0, out=dst[:n])
    buffers.first_d[:n] = d[env_rows]
    buffers.first_w[:n] = first_w
    buffers.first_p[:n] = p[env_rows]
    return roll_forward(sim, steps, codes, hp, fork_pstate, first=True, buffers=buffers, rows=n, literal=literal)[:n]


__all__ = ["RollBuffers", "roll_candidates", "roll_forward", "roll_range"]
