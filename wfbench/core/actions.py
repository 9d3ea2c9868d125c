"""Actions: what each agent's batched decision looks like, and the check that names a malformed one.

A batched action is a dict with one array per agent (:data:`AGENTS`): ``"dispatch"`` (B, M) in
``0..N`` (``N`` the no-op), ``"workforce"`` (B,) in ``0..6`` (0 no-op, ``1 + l`` hire level l,
``4 + l`` let go level l), ``"positioning"`` (B, 2, M) weights in [0, 1] (row 0 places a hire,
row 1 picks who is let go). :func:`validate_actions` converts it to the arrays the compiled core
takes and raises :class:`ActionError`, naming the agent and the index, on a malformed one;
well-formed but impossible actions are ignored and counted by the step (``docs/policies.md``,
"Actions"; ``docs/model.md``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wfbench.core import jit as _jit  # noqa: F401  (first: keys the numba cache of what follows)
from wfbench.core.state import N_WORKFORCE_ACTIONS

AGENTS = ("dispatch", "workforce", "positioning")


class ActionError(ValueError):
    """A malformed action: wrong shape, out of range or not a number."""


def _first_bad(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


@njit(cache=True)
def _all_in(a, hi):
    """Every entry of the flat integer array ``a`` is in 0..hi."""
    for i in range(a.shape[0]):
        if a[i] < 0 or a[i] > hi:
            return False
    return True


@njit(cache=True)
def _all_unit(a):
    """Every entry of the flat float array ``a`` is a number in [0, 1] (NaN fails both tests)."""
    for i in range(a.shape[0]):
        if not (a[i] >= 0.0 and a[i] <= 1.0):
            return False
    return True


@njit(cache=True)
def actions_in_range(dispatch, workforce, positioning, n_dispatch, n_workforce):
    """Every entry of the plain batched actions is valid.

    Dispatch in 0..n_dispatch, workforce in 0..n_workforce, positioning a number in [0, 1].
    """
    return (_all_in(dispatch.reshape(-1), n_dispatch) and _all_in(workforce, n_workforce)
            and _all_unit(positioning.reshape(-1)))


def _plain(a, dtype) -> bool:
    """``a`` is an ndarray of ``dtype`` in the plain form the compiled entry points are bound to."""
    return (type(a) is np.ndarray and a.dtype == dtype and a.flags.c_contiguous and a.flags.aligned
            and a.flags.writeable)


def validate_actions(actions: dict, B: int, M: int, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check and convert a batched action dict; raise :class:`ActionError` on malformed input.

    Well-formed int64 and float arrays take a compiled check; anything else, and every
    malformed input, goes through the numpy checks that name the bad index.
    """
    if type(actions) is dict and len(actions) == 3:
        d, w, p = actions.get("dispatch"), actions.get("workforce"), actions.get("positioning")
        if (_plain(d, np.int64) and d.shape == (B, M) and _plain(w, np.int64) and w.shape == (B,)
                and (_plain(p, np.float64) or _plain(p, np.float32)) and p.shape == (B, 2, M)
                and actions_in_range(d, w, p, N, N_WORKFORCE_ACTIONS - 1)):
            return d, w, p.astype(np.float64, copy=False)
    if not isinstance(actions, dict):
        raise ActionError(f"actions must be a dict with keys {AGENTS}, got {type(actions).__name__}")
    missing = [a for a in AGENTS if a not in actions]
    extra = [a for a in actions if a not in AGENTS]
    if missing or extra:
        raise ActionError(f"actions must have exactly the keys {AGENTS}; missing {missing}, unknown {extra}")

    def integers(agent: str, shape: tuple[int, ...], hi: int) -> np.ndarray:
        a = np.asarray(actions[agent])
        if a.shape != shape:
            raise ActionError(f"{agent} action has shape {a.shape}, expected {shape}")
        if a.dtype.kind not in "iub":
            if a.dtype.kind != "f":
                raise ActionError(f"{agent} action has dtype {a.dtype}; allowed: integers")
            bad = ~np.isfinite(a) | (a != np.round(a))
            if bad.any():
                idx = _first_bad(bad)
                raise ActionError(f"{agent} action: {a[idx].item()!r} at index {idx} is not an integer; "
                                  f"allowed: integers 0..{hi}")
        out = a.astype(np.int64)
        bad = (out < 0) | (out > hi)
        if bad.any():
            idx = _first_bad(bad)
            raise ActionError(f"{agent} action: {out[idx]} at index {idx} is out of range; allowed: integers 0..{hi}")
        return np.ascontiguousarray(out)

    dispatch = integers("dispatch", (B, M), N)
    workforce = integers("workforce", (B,), N_WORKFORCE_ACTIONS - 1)
    pos = np.asarray(actions["positioning"])
    if pos.shape != (B, 2, M):
        raise ActionError(f"positioning action has shape {pos.shape}, expected {(B, 2, M)}")
    if pos.dtype.kind not in "fiub":
        raise ActionError(f"positioning action has dtype {pos.dtype}; allowed: numbers in [0, 1]")
    pos = pos.astype(np.float64)
    bad = ~np.isfinite(pos) | (pos < 0.0) | (pos > 1.0)
    if bad.any():
        idx = _first_bad(bad)
        raise ActionError(f"positioning action: {pos[idx].item()!r} at index {idx} is not allowed; "
                          "allowed: numbers in [0, 1]")
    return dispatch, workforce, np.ascontiguousarray(pos)
