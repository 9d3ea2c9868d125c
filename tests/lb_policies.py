"""Policies that misbehave on purpose, for the leaderboard's isolation tests (loaded as module:attr)."""

from __future__ import annotations

import time

import numpy as np
from wfbench.policies import get


class _Base:
    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self):
        self.inner = get("heuristic")

    def reset(self, seeds):
        self.inner.reset(seeds)


class Raises(_Base):
    def act(self, obs):
        if int(obs["t"][0]) >= 5:
            raise RuntimeError("boom at step 5")
        return self.inner.act(obs)


class Hangs(_Base):
    def act(self, obs):
        time.sleep(3600)


class Garbage(_Base):
    def act(self, obs):
        return {"dispatch": "everyone", "workforce": None, "positioning": [[1, 2]]}


class EatsMemory(_Base):
    def act(self, obs):
        hog = [np.ones(2**27) for _ in range(64)]  # 64 x 1 GiB, touched
        return hog


class Slow(_Base):
    """The heuristic, but each step sleeps: a seed of the tiny track takes about 0.3 s."""

    def act(self, obs):
        time.sleep(0.005)
        return self.inner.act(obs)


def import_fails():
    raise ImportError("this entry point cannot be loaded")


class ClaimsTheFuture(_Base):
    """The heuristic, declaring that it reads the trace: the leaderboard must refuse it."""

    reads_trace = True

    def attach(self, config):
        self.config = config

    def act(self, obs):
        return self.inner.act(obs)
