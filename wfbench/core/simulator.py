"""The batched simulator: holds a trace batch and state and steps them with the compiled core.

``Simulator(scenario, seeds)`` runs ``len(seeds)`` independent episodes side by side.
Actions are a dict with the batched decision of each agent (:mod:`wfbench.core.actions`
says what each holds); malformed actions raise :class:`~wfbench.core.actions.ActionError`
naming the agent and the index, well-formed but impossible ones are ignored and counted.
The compiled functions are called through entry points bound to this simulator's arrays
and spread over threads by :mod:`wfbench.core.entrypoints`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np
from numba import njit

from wfbench.core import jit as _jit  # noqa: F401  (first: keys the numba cache of what follows)
from wfbench.core.actions import AGENTS, ActionError, validate_actions
from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.dynamics import reset_batch, reset_env
from wfbench.core.entrypoints import bind, run_split
from wfbench.core.observation_v2 import WorldKey
from wfbench.core.observe import allocate_obs, observe_env, observe_range, step_observe_range, step_range
from wfbench.core.state import COUNTERS, K_NSW, METRICS, allocate, make_params
from wfbench.core.trace import NEVER, Trace, trace, trace_batch

__all__ = ["AGENTS", "ActionError", "Simulator", "validate_actions"]


def _listed(idx: np.ndarray, limit: int = 10) -> str:
    """Up to ``limit`` indices, then how many more."""
    shown = ", ".join(str(int(i)) for i in idx[:limit])
    return f"[{shown}{f', ... ({len(idx) - limit} more)' if len(idx) > limit else ''}]"


@njit(cache=True, nogil=True)
def reset_observe_at(S, Tr, P, O, idx, with_masks):
    """Reset environments ``idx`` (a 1-D int64 array) from their trace rows and fill their observations.

    The partial reset of :meth:`Simulator.reset`: it touches only the rows of ``idx``, so
    its cost grows with ``len(idx)``, not with the batch.
    """
    for i in range(idx.shape[0]):
        b = idx[i]
        reset_env(b, S, Tr, P)
        observe_env(b, S, P, O, with_masks, True)


# The arrival columns of a trace and their padding (see wfbench.core.trace.stack).
_ARRIVALS = (("arr_t", NEVER), ("arr_x", 0), ("arr_y", 0), ("arr_leave", NEVER))
_PADDING = dict(_ARRIVALS)


def _repad(tr: Trace, A: int) -> Trace:
    """``tr`` with its arrival columns widened to ``A`` (a copy of the four (B, A) arrays, padded as ``stack`` pads)."""
    fields = {}
    for name, fill in _ARRIVALS:
        a = getattr(tr, name)
        out = np.full((a.shape[0], A), fill, dtype=a.dtype)
        out[:, : a.shape[1]] = a
        fields[name] = out
    return tr._replace(**fields)


class Simulator:
    """B independent episodes of one scenario, stepped together by the compiled core.

    Args:
        scenario: a :class:`ScenarioConfig`; a name (a preset, a suite's id such as ``paper-64-v1``
            or a .toml/.json path) is resolved where it enters, by :func:`wfbench.scenario`.
        seeds: one episode per seed.
        keep_series: keep the per-step metrics of every step (``state.series``).
        threads: threads that :meth:`step`, :meth:`observe` and :meth:`step_observe`
            spread the environments over (:func:`run_split`; the results are the same
            bits for any number). ``None`` (default): as many as numba's threads
            (``NUMBA_NUM_THREADS``, all cores unless set). One thread, or a batch of one
            environment, runs in the calling thread alone.
    """

    def __init__(self, scenario: ScenarioConfig, seeds: Sequence[int], keep_series: bool = True,
                 threads: int | None = None):
        self.config = require_config(scenario, "Simulator")
        if threads is not None and not (type(threads) is int and threads >= 1):
            raise ValueError(f"threads = {threads!r} is not allowed; allowed: None or an integer >= 1")
        self.threads = threads
        self._threads = numba.config.NUMBA_NUM_THREADS if threads is None else threads
        seeds = list(seeds)
        if not seeds:
            raise ValueError("seeds is empty; allowed: one or more integers >= 0")
        self.seeds = np.asarray(seeds, dtype=np.int64)
        self.trace = trace_batch(self.config, seeds)
        self.params = make_params(self.config)
        self.B = len(seeds)
        self.M = self.config.max_facilities
        self.N = self.config.max_personnel
        self.state = allocate(self.B, self.config, keep_series)
        self.obs_buffers = allocate_obs(self.B, self.M, self.N)
        self.world_key = WorldKey(self.config, self.B)  # the public parameters every observation carries
        self._started = np.zeros(self.B, dtype=bool)  # environments reset at least once
        self._reset_done = False  # all of them have been (what step and lookahead.fork ask)
        self._bound: dict = {}  # compiled entry points by dispatcher, bound to the tuples in _bound_for
        self._bound_for: tuple | None = None

    def _entry(self, dispatcher, args: tuple, ranged: bool = False):
        """The entry point of a compiled batch function bound to this simulator's arrays (see :func:`bind`).

        Every argument must keep its numba type from call to call: the state, trace,
        parameter and observation tuples are this simulator's own (a new tuple object
        rebinds), actions come from :func:`validate_actions`, flags are bool. A
        ``ranged`` kernel takes the range ``lo, hi`` (two ints) before ``args``.
        """
        b = self._bound_for
        if (b is None or b[0] is not self.state or b[1] is not self.trace or b[2] is not self.params
                or b[3] is not self.obs_buffers):
            self._bound, self._bound_for = {}, (self.state, self.trace, self.params, self.obs_buffers)
        entry = self._bound.get(dispatcher)
        if entry is None:
            entry = self._bound[dispatcher] = bind(dispatcher, *((0, 0) + args if ranged else args))
        return entry

    def call(self, dispatcher, *args):
        """Call a compiled batch function of this simulator's arrays through its bound entry point.

        For layers above the core that run their own compiled kernels over the batch (the
        environments check actions with one): ``dispatcher`` is a numba function, ``args``
        its arguments; the entry point is bound once per dispatcher (:func:`bind`).
        """
        return self._entry(dispatcher, args)(*args)

    def _split(self, kernel, *args) -> None:
        """Run the range kernel ``kernel(lo, hi, *args)`` on every environment, spread over the threads."""
        entry = self._entry(kernel, args, True)
        if self.B == 1 or self._threads == 1:
            entry(0, self.B, *args)
        else:
            run_split(entry, self.B, self._threads, *args)

    # -- episode ------------------------------------------------------------------------------
    def reset(self, indices=None, seeds=None, with_masks: bool = True) -> dict[str, np.ndarray]:
        """Reset every environment, or only those at ``indices``, optionally onto new seeds.

        Args:
            indices: ``None`` (all environments), or the environments to reset: integer
                indices in ``0..B-1`` without repeats, or a boolean mask of shape (B,)
                (``sim.dones`` itself works).
            seeds: ``None`` (each environment replays its own seed, ``self.seeds``), or one
                new seed (an integer >= 0) per reset environment, in the order of
                ``indices`` (B of them when ``indices`` is None). Their traces are
                regenerated and ``self.seeds`` is updated.
            with_masks: fill the action masks of the observation (partial resets only;
                a full reset observes with masks, as it always has).

        Returns:
            The batched observation (the simulator's buffers, overwritten by the next call:
            copy to keep). After a partial reset only the rows at ``indices`` are new;
            the other rows hold what the last ``observe``/``step_observe`` wrote there.

        The environments not at ``indices`` are left exactly as they are, bit for bit: state,
        trace rows, observation rows, seeds. A partial reset runs one compiled call over the
        reset rows only, so its cost grows with their number, not with B. A new seed whose
        trace has more arrivals than the batch's arrival arrays hold widens those four
        (B, A) arrays (``_repad``: a copy of the batch's arrival rows, with a quarter more
        room than needed so that repeated reseeding widens rarely) and rebinds the compiled
        entry points; that one reset costs O(B * A). The padding is never read by a rule,
        so it changes no result (``docs/design.md``, "Batching").

        Raises:
            ValueError: malformed ``indices`` or ``seeds`` (the message says what is allowed).
        """
        if indices is None and seeds is None:
            self.call(reset_batch, self.state, self.trace, self.params)
            self._started[:] = True
            self._reset_done = True
            return self.observe()
        idx = self._indices(indices)
        if seeds is not None:
            self._reseed(idx, seeds)
        if indices is None:  # all environments onto new seeds: the full reset on the new traces
            return self.reset()
        if idx.shape[0]:
            self.call(reset_observe_at, self.state, self.trace, self.params, self.obs_buffers, idx, bool(with_masks))
            self._started[idx] = True
            self._reset_done = bool(self._started.all())
        return self._obs_dict()

    def _indices(self, indices) -> np.ndarray:
        """``indices`` as a plain int64 array of distinct environments; ValueError naming what is wrong."""
        if indices is None:
            return np.arange(self.B, dtype=np.int64)
        a = np.asarray(indices)
        if a.dtype == bool:
            if a.shape != (self.B,):
                raise ValueError(f"indices is a boolean mask of shape {a.shape}; allowed: shape ({self.B},) "
                                 "or integer indices")
            return np.flatnonzero(a).astype(np.int64)
        if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
            raise ValueError(f"indices = {indices!r} is not allowed; allowed: a 1-D sequence of integers "
                             f"in 0..{self.B - 1} or a boolean mask of shape ({self.B},)")
        a = a.astype(np.int64)
        bad = (a < 0) | (a >= self.B)
        if bad.any():
            raise ValueError(f"indices: {int(a[np.argmax(bad)])} is out of range; allowed: 0..{self.B - 1}")
        if np.unique(a).shape[0] != a.shape[0]:
            raise ValueError(f"indices {a.tolist()} repeat an environment; allowed: each index at most once")
        return np.ascontiguousarray(a)

    def _reseed(self, idx: np.ndarray, seeds) -> None:
        """Write the traces of ``seeds`` into rows ``idx`` (widening the arrival arrays if needed)."""
        if isinstance(seeds, (str, bytes)) or np.ndim(seeds) != 1:
            raise ValueError(f"seeds = {seeds!r} is not allowed; allowed: a sequence of integers >= 0, one per "
                             "reset environment")
        seeds = list(seeds)
        if len(seeds) != idx.shape[0]:
            raise ValueError(f"{len(seeds)} seeds for {idx.shape[0]} environments; allowed: one seed per "
                             "reset environment")
        new = [trace(self.config, s) for s in seeds]  # ValueError naming a seed that is not an integer >= 0
        tr = self.trace
        A, need = tr.arr_t.shape[1], max((t.arr_t.shape[1] for t in new), default=0)
        if need > A:
            tr = _repad(tr, max(need, A + A // 4))
        for j, b in enumerate(idx):
            for name, dst, src in zip(Trace._fields, tr, new[j], strict=True):
                row = src[0]
                if name in _PADDING:  # an arrival column: the seed's arrivals, then the padding
                    dst[b, : row.shape[0]] = row
                    dst[b, row.shape[0]:] = _PADDING[name]
                else:
                    dst[b] = row
            self.seeds[b] = new[j].seed[0]
        self.trace = tr

    @property
    def t(self) -> int:
        """The step of the batch's environments; RuntimeError when they are at different steps (use ``state.t``)."""
        t = self.state.t
        t0 = int(t[0])
        if self.B > 1 and (t != t0).any():
            raise RuntimeError("the environments are at different steps (after a partial reset); "
                               "read state.t, one step per environment")
        return t0

    @property
    def dones(self) -> np.ndarray:
        """(B,) bool: the environments whose episode is over (at the horizon); a fresh array."""
        return self.state.t >= self.config.horizon

    @property
    def done(self) -> bool:
        """True when any environment's episode is over, so that :meth:`step` refuses.

        For a batch reset together (as before partial resets): when the episode is over.
        """
        t = self.state.t
        if self.B == 1:
            return int(t[0]) >= self.config.horizon
        return bool((t >= self.config.horizon).any())

    def observe(self, with_masks: bool = True) -> dict[str, np.ndarray]:
        """The batched observation. Arrays are buffers overwritten by the next call: copy to keep."""
        self._split(observe_range, self.state, self.params, self.obs_buffers, bool(with_masks))
        return self._obs_dict()

    def _obs_dict(self) -> dict[str, np.ndarray]:
        obs = self.obs_buffers._asdict()
        obs["t"] = self.state.t
        obs["world"] = self.world_key(self.state.t)
        return obs

    def check_ready(self) -> None:
        """Raise ``RuntimeError`` unless a step may run now: after ``reset`` and before the horizon."""
        if not self._reset_done:
            if self._started.any():
                waiting = np.flatnonzero(~self._started)
                raise RuntimeError(f"environment(s) {_listed(waiting)} were never reset; call reset() or "
                                   "reset(indices=...) on them before step()")
            raise RuntimeError("call reset() before step()")
        if self.done:
            if self.B == 1:
                raise RuntimeError(f"the episode is over (horizon {self.config.horizon}); call reset()")
            over = np.flatnonzero(self.dones)
            raise RuntimeError(f"the episode is over (horizon {self.config.horizon}) for environment(s) "
                               f"{_listed(over)} of {self.B}; call reset(indices=np.flatnonzero(sim.dones)) "
                               "(a step moves every environment, none is frozen)")

    def _checked(self, actions: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.check_ready()
        return validate_actions(actions, self.B, self.M, self.N)

    def step(self, actions: dict) -> np.ndarray:
        """Apply one batched action; returns the rewards (B,) of the step (NSW_t)."""
        d, w, p = self._checked(actions)
        self._split(step_range, self.state, self.trace, self.params, d, w, p)
        return self.state.last[:, K_NSW].copy()

    def step_observe(self, actions: dict, with_masks: bool = True) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``step`` then ``observe`` in one compiled call: the rewards (B,) and the new observation.

        The fast path of the environments: the compiled call is bound to this
        simulator's arrays once (:func:`bind`), so a step of a single environment costs
        a few microseconds of call overhead, not tens.
        """
        d, w, p = self._checked(actions)
        return self.step_observe_checked(d, w, p, with_masks)

    def step_observe_checked(self, d: np.ndarray, w: np.ndarray, p: np.ndarray,
                            with_masks: bool = True) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``step_observe`` for a caller that has called :meth:`check_ready` and checked the actions.

        The actions are what :func:`validate_actions` returns: plain int64 (B, M) and (B,),
        float64 (B, 2, M), every entry in range.
        """
        self._split(step_observe_range, self.state, self.trace, self.params, self.obs_buffers, d, w, p,
                    bool(with_masks))
        return self.state.last[:, K_NSW].copy(), self._obs_dict()

    # -- results -----------------------------------------------------------------------------
    def counters(self, b: int | None = None) -> dict[str, np.ndarray]:
        c = self.state.counters if b is None else self.state.counters[b]
        return {name: c[..., i].copy() for i, name in enumerate(COUNTERS)}

    def episode_means(self) -> dict[str, np.ndarray]:
        """Mean of each per-step metric over the steps run so far, per environment."""
        steps = np.maximum(self.state.t, 1)[:, None]
        means = self.state.totals / steps
        return {name: means[:, i] for i, name in enumerate(METRICS)}
