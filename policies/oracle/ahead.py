"""What a second process compiles for the oracle on a cold cache (issue #54, "the first hour").

The oracle's first ``reset`` compiles the every-rule roll-forward (``roll_range`` with the rule
codes at run time), the longest compilation of its first ``evaluate``: on one core it types
every rule's kernel on the way, the dispatch kernels first and the positioning ones last. The
facility-location kernels (:data:`KERNELS`: the p-median of the ``facility`` positioning rules,
dense and sparse, with their solvers) are about a third of it. :func:`oracle_job` hands them to
the second process first, compiled for the types the roll-forward passes them (those of the
kernels' observation tuple, policy state and rows, which ``act_batch`` passes too); the runner
then queues the simulator's step (the roll-forward inlines its workforce kernel, at its end),
and last what the oracle's own ``compile_ahead`` names (the built-in rules its candidates act
with, which its first live ``act`` needs after the roll-forward). This process compiles the
dispatch and workforce rules meanwhile, and when it gets to what the second process compiles
it loads each from disk as soon as it is there (:func:`wfbench.harness.runner.wait_on_miss`).

It lives beside the oracle, not in it: ``best.py`` is one of the files whose bytes decide the
oracle's committed pieces (``episodes.decisive_files``), and where code is compiled decides
no number.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import typeof, types
from wfbench.policies import kernels as K
from wfbench.policies.kernels.act import act_range
from wfbench.policies.kernels.positioning import positioning_facility, positioning_facility_sparse

from wfbench.core.observe import allocate_obs

# in the order the roll-forward reaches them (P_FACILITY's branch before P_FACILITY_SPARSE's)
KERNELS = (positioning_facility, positioning_facility_sparse)


def kernel_signature() -> tuple:
    """The argument types the roll-forward and ``act_batch`` call :data:`KERNELS` with.

    ``(b, O, S, hp row, positioning row, t)``: the environment index and the step as int64, the
    kernels' observation tuple and policy state, a row of the (3, ``len(HP_FIELDS)``)
    hyper-parameters and the environment's (2, M) positioning block. Array types do not depend
    on the sizes, so one environment of one facility and one person gives them.
    """
    hp = np.zeros((3, len(K.HP_FIELDS)))
    positioning = np.zeros((1, 2, 1))
    return (types.int64, typeof(allocate_obs(1, 1, 1)), typeof(K.allocate_state(1, 1, 1)), typeof(hp[2]),
            typeof(positioning[0]), types.int64)


def compile_kernels() -> None:
    """Compile (or load) :data:`KERNELS` for :func:`kernel_signature` into numba's on-disk cache."""
    sig = kernel_signature()
    for kernel in KERNELS:
        kernel.compile(sig)


def oracle_job(policy: Any, cached: Callable[[Any], bool]) -> tuple[tuple, tuple] | None:
    """The second process's jobs for a policy with a ``compile_ahead`` hook (the oracles), or None.

    Two ``(what, job, args, waits)``: :func:`compile_kernels` first (``waits``: :data:`KERNELS`),
    and last the hook's own job, the built-in rules the candidates act with (``waits``: their
    ``act_range``), which their first live ``act`` needs after the roll-forward; the runner
    queues the simulator's step between the two. None where the hook has nothing (warm).
    """
    job = policy.compile_ahead(cached)
    if job is None:
        return None
    what, fn, args = job
    return (("the oracle's facility-location kernels", compile_kernels, (), KERNELS),
            (what, fn, args, (act_range,)))


__all__ = ["KERNELS", "compile_kernels", "kernel_signature", "oracle_job"]
