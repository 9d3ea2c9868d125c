"""What a PPO update holds in memory, as a function of the batch and the network (issue #44).

What grows is the update: a minibatch is one forward pass whose activations autograd keeps, so
its memory is ``B / minibatches * T`` rows times the bytes a row saves. :func:`row_bytes` is that
estimate (float32, fitted to the bytes autograd saves on CPU at small sizes, within 15%:
tests/train/test_memory.py); :func:`update_envs` bounds the environments of one forward and
backward pass, so that a larger minibatch runs in chunks whose gradients add up
(``wfbench.train.ppo.Trainer``). The measurements and the per-row formula:
``docs/performance.md``, "Memory of paper at B = 4096".

On CPU, :func:`keep_freed_memory` has glibc keep the update's freed blocks for the next
minibatch instead of handing them back to the kernel and faulting them in again (the
speed, never the bits: ``docs/performance.md``, "Training across the training split").
"""

from __future__ import annotations

import ctypes
import math
import os
import platform
import sys

# glibc's mallopt parameters (malloc.h) and the values the trainers set: blocks up to 32 MiB (glibc's largest mmap
# threshold on 64-bit) come from the heap, and up to 1 GiB of free memory at the heap's top stays there
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
KEEP_TRIM_BYTES, KEEP_MMAP_BYTES = 1 << 30, 32 << 20
MALLOC_ENV = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_", "MALLOC_MMAP_MAX_")
FLOAT = 4  # bytes: the estimate is for float32 activations (bf16 autocast keeps about half for the linear layers)


def row_bytes(network, M: int, N: int) -> float:
    """Bytes autograd keeps per row (one env-step) of a forward pass of ``network`` (a config), M + N slots."""
    if getattr(network, "arch", None) == "scalefree":
        d, lstm, pf = network.d, network.lstm, network.pos_freqs
        fac_in, per_in = 7 + 2 + 4 * pf, 14 + 2 * (2 + 4 * pf)  # the entity rows' widths (scalefree.featurize)
        floats = 2.2 * (M + N) * d + 1.1 * (M * fac_in + N * per_in) + 42 * lstm + 27 * d
        return FLOAT * floats
    if hasattr(network, "members"):  # independent agents: one network each
        return sum(row_bytes(m, M, N) for _, m in network.members)
    d, ff, heads = network.d, network.ff, network.heads
    attention = (M + N) * d * (network.n_blocks * (20 + 4 * ff) + network.n_fusion * (10 + 2 * ff))
    bias = 2 * network.n_blocks * heads * M * N
    floats = 0.92 * attention + 1.15 * bias + 11 * (M + N) * d + 5 * M * N + 16 * (M + N) + 75 * network.lstm
    return FLOAT * floats


def update_bytes_per_env(network, M: int, N: int, T: int, minibatches: int) -> float:
    """Bytes of the update's activations per environment of the batch B (a minibatch is B / ``minibatches``)."""
    return row_bytes(network, M, N) * T / minibatches


def update_envs(network, M: int, N: int, T: int, budget_bytes: float) -> int:
    """The environments (of T rows each) one forward and backward pass may hold within ``budget_bytes`` (at least 1)."""
    return max(1, math.floor(budget_bytes / (row_bytes(network, M, N) * T)))


def keep_freed_memory() -> bool:
    """Have glibc's malloc keep freed memory in this process for reuse; whether it was set (Linux and glibc only).

    A CPU update allocates and frees activations of megabytes per minibatch (``scalefree``
    on ``suite-v1:train``: (1024, 50, 32) float32 blocks of 6.5 MB). glibc's defaults serve
    a block above its mmap threshold (128 KiB, raised by each freed mapped block) by a fresh
    mapping and give the heap's top back to the kernel above its trim threshold (twice the
    other), so the same megabytes were faulted in, a page at a time, every minibatch: 11,000
    to 21,000 page faults an update of 64 environments against 1,000 to 4,000 with this.
    Both thresholds are set, fixed (mallopt stops glibc's adjusting them): blocks up to
    32 MiB come from the heap and up to 1 GiB of free memory stays at its top. The memory
    a process holds stays near its peak; what it computes does not change (the allocator
    returns 64-byte aligned blocks either way). Left alone when the environment sets any
    of glibc's ``MALLOC_*`` thresholds (the user's choice), and on other systems.
    """
    if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
        return False
    if any(k in os.environ for k in MALLOC_ENV):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, KEEP_MMAP_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, KEEP_TRIM_BYTES))
