"""A user's policy: the paper's heuristic, wrapped the way a user would start."""

from __future__ import annotations

from wfbench.policies import get


class MyPolicy:
    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self):
        self.inner = get("heuristic")

    def reset(self, seeds):
        self.inner.reset(seeds)

    def act(self, obs):
        return self.inner.act(obs)
