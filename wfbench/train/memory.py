"""What a PPO update holds in memory, as a function of the batch and the network (issue #44).

The rollout's own tensors are small (the raw observation of paper-64 is a few KiB per
env-step). What grows is the update: a minibatch of B / ``minibatches`` environments
with all T of their steps is one forward pass whose activations autograd keeps for the
backward pass, so the memory is ``B / minibatches * T`` rows times the bytes a row saves.
For the ``paper`` network that is the attention blocks' per-entity activations, about
``28 * (M + N) * d`` floats a block for ff = 2 (each attention call keeps its normalized
inputs, q, k, v, its output and the feed-forward's 2 * ff * d wide hidden rows) and the
cross-attention's ``heads * M * N`` additive bias twice a block: on paper-64
(M = N = 50 slots), d = 64, heads 4, two blocks, about 2.3 MB a row, so 36 MB per
environment of B at T = 32 with two minibatches. The heads count little (the attention
kernel does not keep its (M, N) weights on CPU, nor CUDA's fused kernels; the math kernel
does). The scale-free network keeps about 50 KB a row on paper-64.

:func:`row_bytes` is the estimate (float32, fitted to the bytes autograd saves, measured
with ``torch.autograd.graph.saved_tensors_hooks`` on CPU at small sizes; within 15% of them,
tests/train/test_memory.py). :func:`update_envs` bounds the update: the environments of
one forward and backward pass, so that a minibatch larger than the memory at hand is run
in chunks whose gradients add up (``wfbench.train.ppo.Trainer``, ``update_envs``).
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
