"""Hostile policies for the containment tests, loaded as ``tests.data.user_policies.hostile:Name``.

Each plays the heuristic until it misbehaves in one way: raises, hangs (asleep or
spinning), returns garbage, or eats memory.
"""

from __future__ import annotations

import resource
import time

import numpy as np
from numba.core.compiler_lock import global_compiler_lock
from wfbench.policies import get


class _Heuristic:
    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self):
        self.inner = get("heuristic")

    def reset(self, seeds):
        self.inner.reset(seeds)

    def act(self, obs):
        return self.inner.act(obs)


class Raises(_Heuristic):
    def act(self, obs):
        if int(obs["t"][0]) >= 3:
            raise RuntimeError("boom at step 3")  # the line the error must name
        return self.inner.act(obs)


class Hangs(_Heuristic):
    def act(self, obs):
        if int(obs["t"][0]) >= 2:
            time.sleep(3600)  # the line the timeout must name
        return self.inner.act(obs)


class Spins(_Heuristic):
    def act(self, obs):
        while True:  # a busy loop that never sleeps
            pass


class Garbage(_Heuristic):
    def act(self, obs):
        return {"dispatch": "everyone", "workforce": None, "positioning": [[1, 2]]}


class EatsMemory(_Heuristic):
    def act(self, obs):
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft == resource.RLIM_INFINITY:  # never hog a machine that has no limit set
            raise RuntimeError("EatsMemory runs only under a memory limit (RLIMIT_AS)")
        hog = []
        while True:  # 256 MiB blocks until the limit stops it; RLIMIT_AS counts address space, so they are
            hog.append(np.empty(2**25))  # not touched (touching 1.5 GB outlasted the 2 s act timeout on a busy VM)


class BrokenInit(_Heuristic):
    def __init__(self):
        self.ratio = 1 / 0  # the constructor fails: a load error


class CompilesSlowly(_Heuristic):
    """Holds numba's compiler lock for a second on its first call, as a cold-cache compile does."""

    def act(self, obs):
        if int(obs["t"][0]) == 0:
            with global_compiler_lock:
                time.sleep(1.0)
        return self.inner.act(obs)


class SleepsOnce(_Heuristic):
    """The same second, spent by the policy itself."""

    def act(self, obs):
        if int(obs["t"][0]) == 0:
            time.sleep(1.0)
        return self.inner.act(obs)
