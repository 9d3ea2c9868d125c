"""Counter-based random numbers: a draw is a pure function of (key, stream, i, j, k).

The trace indexes every draw by *what it is for* (the k-th failure of slot f; the v-th visit
to request r of slot f), not when it is used. Instead of storing ``slots x requests x visits``
numbers, it holds one 64-bit key per seed (from ``numpy.random.SeedSequence``) and computes each
draw on demand with the SplitMix64 finalizer (Steele, Lea & Flood 2014), so a seed is
bit-identical alone or in a batch. Policies that randomize use the same construction with their
own key (``docs/design.md``, "The trace and common random numbers"; ``docs/model.md``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wfbench.core import jit as _jit  # noqa: F401  (first: keys the numba cache of what follows)

# Stream identifiers: one per purpose.
STREAM_FAILURE = 1
STREAM_REPAIR = 2
STREAM_PLACEMENT = 3
# Policy streams (a policy's key is separate from the environment's).
STREAM_POLICY_DISPATCH = 11
STREAM_POLICY_WORKFORCE = 12
STREAM_POLICY_POSITIONING = 13

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0  # 2**-53


@njit(cache=True, inline="always")
def _mix(z):
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@njit(cache=True)
def uniform(key, stream, i, j, k):
    """A uniform draw in [0, 1) for index (stream, i, j, k) under ``key``.

    Indices are non-negative integers below 2**32 (i, j, k) and 2**16 (stream).
    """
    z = np.uint64(key)
    z = _mix(z + _GOLDEN * np.uint64(stream + 1))
    z = _mix(z + _GOLDEN * np.uint64(i + 1))
    z = _mix(z + _GOLDEN * np.uint64(j + 1))
    z = _mix(z + _GOLDEN * np.uint64(k + 1))
    return np.float64(z >> _S11) * _INV53


@njit(cache=True)
def exponential(key, stream, i, j, k):
    """A unit-mean exponential draw, ``-log(1 - u)``."""
    return -np.log1p(-uniform(key, stream, i, j, k))


@njit(cache=True)
def normal(key, stream, i, j, k):
    """A standard normal draw by Box-Muller from two counter draws."""
    u1 = uniform(key, stream, i, j, 2 * k)
    u2 = uniform(key, stream, i, j, 2 * k + 1)
    return np.sqrt(-2.0 * np.log1p(-u1)) * np.cos(2.0 * np.pi * u2)


def key_from_seed(*entropy: int) -> np.uint64:
    """A 64-bit key from integer entropy through ``numpy.random.SeedSequence``."""
    state = np.random.SeedSequence(list(entropy)).generate_state(2, dtype=np.uint32)
    return np.uint64((int(state[0]) << 32) | int(state[1]))
