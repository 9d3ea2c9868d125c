"""What a PPO update holds in memory, as a function of the batch and the network (issue #44).

What grows is the update: a minibatch is one forward pass whose activations autograd keeps, so
its memory is ``B / minibatches * T`` rows times the bytes a row saves. :func:`row_bytes` is that
estimate (float32, fitted to the bytes autograd saves on CPU at small sizes, within 15%:
tests/train/test_memory.py); :func:`update_envs` bounds the environments of one forward and
backward pass, so that a larger minibatch runs in chunks whose gradients add up
(``wfbench.train.ppo.Trainer``). The measurements and the per-row formula:
``docs/performance.md``, "Memory of paper at B = 4096".
"""

from __future__ import annotations

import math

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
