"""Switching among a method's training seeds: the learned side spends compute choosing its network (issue #52).

A method trained with five seeds gives five networks of one recipe whose held-out scores are
far apart (docs/suite.md, "Learned methods over training seeds"), and which of them suits an
unseen world is not known in advance. :class:`SeedSwitch` keeps all of them and, every ``R``
steps, plays each on the same K futures sampled from the belief (never the trace) to the end
of the episode, each network in its own sampling mode from its own memory of the episode so far;
each environment then follows the network whose futures summed the most NSW, but leaves the
one it follows only where the paired advantage over the K worlds exceeds ``z`` standard
errors (:func:`~wfbench.policies.lookahead.search.beyond_noise`). This is parallel rollout
over several base policies (Chang, Givan and Chong 2004; Bertsekas' rollout with several
heuristics): with exact futures it is at least as good as the best of its networks, from the
state it is in; with sampled ones, the noise test keeps it with its incumbent (the shipped
pick, at the start) where the futures cannot tell the networks apart.

Each network acts in its own mode at the root; dispatch, workforce and positioning all come
from the network followed. While a later deliberation is due every network steps on every
observation, so that its memory of the episode is whole when it is chosen; after the last one,
only the networks followed act. ``docs/policies.md``, "switch-scalefree-general".
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies.lookahead.knobs import positive, whole
from wfbench.policies.lookahead.network_rollout import PURPOSE_NOISE
from wfbench.policies.lookahead.rollout import start_belief
from wfbench.policies.lookahead.search import beyond_noise
from wfbench.policies.protocol import seeds_array

from wfbench.core.actions import AGENTS
from wfbench.core.belief import Belief
from wfbench.core.config import ScenarioConfig, require_config

# budget presets: (K, R, z), named by the CPU time per env-step they aim at on paper-64 (one core, whole episodes);
# chosen on public seeds 1000-1009 of three training worlds (docs/policies.md, "switch-scalefree-general"). R = 800,
# the suite's horizon: one deliberation, at the start. "5ms" halves the futures, so that the held-out split's mean,
# city's 40 ms included, falls within the frontier's 10 ms class
BUDGETS: dict[str, tuple[int, int, float]] = {
    "5ms": (2, 800, 1.0),
    "10ms": (4, 800, 1.0),
}
DEFAULT_BUDGET = "10ms"
KNOBS = {"K": ("sampled futures per network", "an integer >= 2"),
         "R": ("steps between two deliberations (the first at step 0)", "an integer >= 1"),
         "z": ("standard errors a network's paired advantage over the one followed must exceed", "a number > 0")}
FUTURES = ("greedy", "sample")


def knob(name: str, value: Any) -> int | float:
    """``value`` as a switch knob (:data:`KNOBS`); ValueError of one line naming the knob and what is allowed."""
    what, allowed = KNOBS[name]
    if name == "z":
        return positive("switch", name, value, what, allowed)
    return whole("switch", name, value, what, 2 if name == "K" else 1, allowed)


def budget(name: str) -> tuple[int, int, float]:
    """The (K, R, z) of a budget preset; ValueError of one line naming the presets otherwise."""
    if name not in BUDGETS:
        raise ValueError(f"switch budget {name!r} is not allowed; allowed: {', '.join(BUDGETS)}")
    return BUDGETS[name]


class SeedSwitch:
    """Follow, per environment, the network among ``members`` whose sampled futures score best (module docstring).

    Args:
        members: networks deciding dispatch, workforce and positioning
            (:class:`~wfbench.policies.neural.policy.NetworkPolicy`), the first the incumbent every
            environment follows at the start (the method's shipped pick).
        K, R, z: the knobs (:data:`KNOBS`); None takes the ``budget`` preset's.
        budget: a preset of :data:`BUDGETS`.
        futures: how the networks play the futures, :data:`FUTURES`: ``"sample"`` (the default: as
            each acts at the root, in its sampling mode, the noise keyed by world and the same key for
            every network) or ``"greedy"`` (no policy noise; measured lower, docs/policies.md).
        scenario: the public config of the world; None: from :meth:`set_world`, else the first
            observation.
        seed: the policy's own seed, mixed into its belief keys (and the futures' noise).
        name: the policy's name.
    """

    decisions = AGENTS
    reads_trace = False

    def __init__(self, members: Sequence[Any], K: int | None = None, R: int | None = None, z: float | None = None,
                 budget: str = DEFAULT_BUDGET, futures: str = "sample", scenario: ScenarioConfig | None = None,
                 seed: int = 0, name: str | None = None):
        members = list(members)
        if len(members) < 2:
            raise ValueError(f"switch members: {len(members)} given; allowed: two or more networks")
        for m in members:
            if not (hasattr(m, "model") and set(getattr(m, "decisions", ())) == set(AGENTS)):
                raise ValueError(f"switch member {getattr(m, 'name', m)!r} is not a network deciding dispatch, "
                                 "workforce and positioning; allowed: NetworkPolicy objects such as "
                                 "scalefree-general#seed0")
        if futures not in FUTURES:
            raise ValueError(f"switch futures {futures!r} is not allowed; allowed: {', '.join(FUTURES)} (how the "
                             "networks play the sampled worlds)")
        preset = globals()["budget"](budget)
        given = dict(zip(KNOBS, (K, R, z), strict=True))
        self.K, self.R, self.z = (knob(n, preset[i] if v is None else v) for i, (n, v) in enumerate(given.items()))
        self.members = members
        self.futures = futures
        self.seed = int(seed)
        self.name = name or f"switch-{getattr(members[0], 'name', 'network')}"
        self.config = None if scenario is None else require_config(scenario, f"{self.name} scenario=")
        self.trained_on = getattr(members[0], "trained_on", None)
        self.belief: Belief | None = None
        self.follow: np.ndarray | None = None  # (B,) the member each environment follows
        self.last_test: dict[int, tuple[list[int], np.ndarray, np.ndarray]] = {}
        self.last_scores: np.ndarray | None = None  # (B, members) mean NSW summed over the futures, at a deliberation
        self.timing: dict[str, float] = {}

    def settings(self) -> dict[str, Any]:
        return {"K": self.K, "R": self.R, "z": self.z, "futures": self.futures,
                "members": [getattr(m, "name", type(m).__name__) for m in self.members]}

    def set_world(self, config: ScenarioConfig) -> None:
        """The public config of the world (the evaluator's, before ``reset``); replaces ``scenario=``."""
        self.config = require_config(config, f"{self.name}.set_world")

    def reset(self, seeds: int | Sequence[int]) -> None:
        self._seeds = seeds_array(seeds)
        for m in self.members:
            m.reset(self._seeds)
        self.belief = None
        self.follow = np.zeros(len(self._seeds), dtype=np.int64)

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        from wfbench.policies.neural.policy import NetworkPolicy

        config, B = start_belief(self, obs)
        self.horizon = config.horizon
        self.B = B
        self.fork = None
        self.players = [NetworkPolicy(m.model, mode=self.futures, device=str(m.device), seed=m.seed,
                                      name=f"{self.name}/{i}", threads=m.threads) for i, m in enumerate(self.members)]
        self.acting = set(range(len(self.members)))  # the members that step on every observation
        self.timing = {"steps": 0.0, "act_s": 0.0, "decisions": 0.0, "switches": 0.0}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        start = time.perf_counter()
        t = int(np.asarray(obs["t"]).reshape(-1)[0])
        if self.belief is None or t == 0 and self.belief.t[0] > 0:
            if self.belief is not None:  # a new episode on the same seeds
                self.reset(self._seeds)
            self._start(obs)
        self.belief.update(obs)
        deliberate = t % self.R == 0
        self.last_scores = None
        later = (t // self.R + 1) * self.R < self.horizon  # another deliberation is due: every member keeps up
        if not (deliberate or later):
            self.acting = {int(m) for m in np.unique(self.follow)}
        actions = {m: {k: np.asarray(v) for k, v in self.members[m].act(obs).items()} for m in sorted(self.acting)}
        if deliberate:
            self._deliberate(obs, actions, t)
        out = {k: np.array(v, copy=True) for k, v in actions[int(self.follow[0])].items()}
        for b in np.flatnonzero(self.follow != self.follow[0]):
            for k in out:
                out[k][b] = actions[int(self.follow[b])][k][b]
        self.timing["steps"] += 1
        self.timing["act_s"] += time.perf_counter() - start
        return out

    def _deliberate(self, obs, actions: dict[int, dict[str, np.ndarray]], t: int) -> None:
        """Play every member on the same K futures of every environment to the end; follow a winner beyond the noise."""
        import torch

        B, K = self.B, self.K
        env_idx = np.repeat(np.arange(B, dtype=np.int64), K)
        rows_k = np.tile(np.arange(K, dtype=np.int64), B)
        n = B * K
        if self.fork is None:
            self.fork = self.belief.simulator(n)
        steps = self.horizon - t
        score = np.empty((len(self.members), B, K))
        idx = torch.as_tensor(env_idx)
        for m, member in enumerate(self.members):
            self.belief.sample_into(self.fork, env_idx, rows_k, None)  # world k of each environment, to the end
            p = self.players[m]
            h, c = member._state  # after this step's act: the member's memory of the episode so far
            p._state = (h[:, idx].clone(), c[:, idx].clone())
            p._starts = torch.zeros(1, n, device=h.device)
            if self.futures == "sample":  # world k's noise, the same key for every member
                p._rngs = [np.random.default_rng([int(self._seeds[e]), self.seed, PURPOSE_NOISE, t, int(k)])
                           for e, k in zip(env_idx, rows_k, strict=True)]
            first = {k: v[env_idx] for k, v in actions[m].items()}
            total, fobs = self.fork.step_observe(first)
            total = np.asarray(total, dtype=np.float64).copy()
            for _ in range(steps - 1):
                r, fobs = self.fork.step_observe(p.act(fobs))
                total += r
            score[m] = total.reshape(B, K)
        self.timing["decisions"] += B
        self.last_scores = score.mean(2).T.copy()
        self.last_test = {}
        for b in range(B):
            order = [int(self.follow[b])] + [m for m in range(len(self.members)) if m != self.follow[b]]
            best, mean, se = beyond_noise(score[order, b], self.z)
            self.last_test[b] = (order, mean, se)
            if best:
                self.follow[b] = order[best]
                self.timing["switches"] += 1


__all__ = ["BUDGETS", "DEFAULT_BUDGET", "FUTURES", "KNOBS", "SeedSwitch", "budget", "knob"]
