"""What a second process compiles for a rollout on a cold cache (issue #54, "the first hour").

:func:`rollout_job` is what :func:`wfbench.harness.runner.start_compile_ahead` asks of a
:class:`~wfbench.policies.lookahead.rollout.Rollout`: its futures' roll-forward, the longest
compilation of its first ``act``, which that act reaches last (after the belief and the base's
rules). A second process compiles it into numba's on-disk cache meanwhile, and the first loads
it when it gets there. It lives beside the rollout, not in it: ``rollout.py`` is one of the
files whose bytes decide a rollout's committed pieces (``episodes.decisive_files``), and
where code is compiled decides no number.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
from wfbench.policies.kernels.forward import roll_candidates, roll_range
from wfbench.policies.lookahead.rollout import Rollout

from wfbench.core.simulator import Simulator


def rollout_job(policy: Any, cached: Callable[[Any], bool]) -> tuple[str, Callable, tuple, tuple] | None:
    """The second process's job for ``policy`` after ``set_world``: ``(what, job, args, waits)``, or None.

    ``waits``: the roll-forward, which this process's first act waits for on a miss. None: not a
    :class:`Rollout`, no public world to build it for, or warm (``cached(dispatcher)``: numba's
    cache holds a compilation of the roll-forward).
    """
    if type(policy) is not Rollout or policy.config is None or cached(roll_range):
        return None
    # a copy as it is now: the pool pickles the job later, in its own thread, while this one acts
    return "the rollout's futures", compile_roll, (copy.deepcopy(policy),), (roll_range,)


def compile_roll(policy: Rollout) -> None:
    """One roll-forward of ``policy``'s futures, thrown away (a copy: the caller's is untouched).

    The policy starts an episode of one environment of its public world as its first ``act``
    would, and rolls its futures' plan from the fork as it is allocated (reset, no world sampled
    into it), with the types and literal codes its decisions pass: numba compiles (or loads) and
    caches the same roll-forward.
    """
    obs = Simulator(policy.config.replace(horizon=2), [0], keep_series=False).reset()
    policy.reset([0])
    policy._start(obs)
    B, M, N = policy.B, policy.M, policy.N
    d = np.full((B, M), N, dtype=np.int64)
    p = np.zeros((B, 2, M), dtype=np.float64)
    roll_candidates(policy.fork, policy.H, policy.f_codes, policy.f_hp, policy.pstate, policy.fork_pstate,
                    policy.buffers, np.zeros(1, dtype=np.int64), [0], d, p, literal=True)
