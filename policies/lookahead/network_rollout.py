"""Rollout with a trained network as the base: lookahead on top of a learned policy (issue #43).

:class:`NetworkRollout` is :class:`~wfbench.policies.lookahead.rollout.Rollout` with a network
(a :class:`~wfbench.policies.neural.policy.NetworkPolicy` deciding all three decisions, e.g.
``scalefree-general``) in place of the compiled composite: a copy of the network, from its
recurrent state now, plays every later step of the K sampled worlds, and its sampling noise is
keyed so that every candidate meets the same noise in world k (common random numbers). The
futures step the batched simulator from Python, so a decision costs H forward passes. The
method and its measured cost: ``docs/policies.md``, "rollout-scalefree-general".
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies.lookahead.rollout import (
    DECIDE,
    DEFAULT_BUDGET,
    RolloutBase,
    candidate_rows,
    check_decide,
    pick_best,
    plays_sparse,
    start_belief,
)
from wfbench.policies.protocol import seeds_array

from wfbench.core.actions import AGENTS
from wfbench.core.config import ScenarioConfig

PURPOSE_NOISE = 0x4E52  # the copy's sampling noise: a purpose of its own beside the belief's keys
# decide="auto": on a world as large as city the network hires or lets go on nearly every step (58 of the first 60 of
# public seed 1000), so deliberating wherever it asks costs a decision a step (1.4 CPU s per env-step for the
# search's 10 ms preset); there it deliberates every R steps only, as the rollouts' sparse presets do
DECIDE_AUTO = "auto"
DECIDE_AUTO_DOC = "every R steps only on a world as large as city, where the base hires or lets go elsewhere"


class NetworkRollout(RolloutBase):
    """Rollout of a network ``base`` on K sampled futures of H steps (module docstring).

    Args:
        base: a :class:`~wfbench.policies.neural.policy.NetworkPolicy` that decides dispatch,
            workforce and positioning (``policies.get("scalefree-general")``).
        K, H, R: the knobs of :class:`~wfbench.policies.lookahead.rollout.Rollout`; None takes the
            ``budget`` preset's.
        budget: a preset of :data:`~wfbench.policies.lookahead.rollout.BUDGETS` for the knobs not given.
        scenario: the public config of the world; None: from :meth:`set_world`, else the first observation.
        seed: the policy's own seed, mixed into its belief keys and the copy's noise.
        name: the policy's name.
        decide: when it deliberates: ``"base"`` where the network hires or lets go and every R
            steps, ``"period"`` every R steps only, ``"auto"`` (:data:`DECIDE_AUTO`) the period on a
            world as large as ``city`` (:func:`~wfbench.policies.lookahead.rollout.plays_sparse`),
            where the network asks on nearly every step, and the base rule on any other.
    """

    def __init__(self, base: Any, K: int | None = None, H: int | None = None, R: int | None = None,
                 budget: str = DEFAULT_BUDGET, scenario: ScenarioConfig | None = None, seed: int = 0,
                 name: str | None = None, decide: str = "base"):
        check_decide(decide, {**DECIDE, DECIDE_AUTO: DECIDE_AUTO_DOC})
        self.decide = decide
        self.period = decide == "period"  # what this episode plays (decide="auto": set by the world's size)
        if not (hasattr(base, "model") and set(getattr(base, "decisions", ())) == set(AGENTS)):
            raise ValueError(f"rollout base {getattr(base, 'name', base)!r} is not a network deciding dispatch, "
                             "workforce and positioning; allowed: a NetworkPolicy such as scalefree-general")
        name = name or f"rollout-{getattr(base, 'name', 'network')}"
        super().__init__(base, K, H, R, budget, scenario, seed, name)
        self.trained_on = getattr(base, "trained_on", None)

    def reset(self, seeds: int | Sequence[int]) -> None:
        self._seeds = seeds_array(seeds)
        self.base.reset(self._seeds)
        self.belief = None

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        from wfbench.policies.neural.policy import NetworkPolicy

        config, B = start_belief(self, obs)
        self.horizon = config.horizon
        self.forks: dict[int, Any] = {}  # rows -> a fork of that many rows, allocated once
        b = self.base
        self.player = NetworkPolicy(b.model, mode=b.mode, device=str(b.device), seed=b.seed, name=f"{self.name}/copy",
                                    threads=b.threads)
        self.B = B
        if self.decide == DECIDE_AUTO:  # the world's size is public: nothing a deployable policy may not read
            self.period = plays_sparse(obs["facilities"].shape[1], obs["personnel"].shape[1])
        self.timing = {"steps": 0.0, "act_s": 0.0, "decisions": 0.0, "rolls": 0.0}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        start = time.perf_counter()
        if self.belief is None or int(np.asarray(obs["t"]).reshape(-1)[0]) == 0 and self.belief.t[0] > 0:
            if self.belief is not None:
                self.base.reset(self._seeds)
            self._start(obs)
        self.belief.update(obs)
        self._prior = self.base._state, self.base._starts  # the memory before this step (a search re-reads its heads)
        action = self.base.act(obs)
        action = {k: np.array(v, copy=True) for k, v in action.items()}
        t = np.asarray(obs["t"], dtype=np.int64)
        decide = (t % self.R == 0) if self.period else self._asks(obs, action) | (t % self.R == 0)
        self.last_scores = None
        if decide.any():
            self._decide(obs, np.flatnonzero(decide), action, int(t[0]))
        self.timing["steps"] += 1
        self.timing["act_s"] += time.perf_counter() - start
        return action

    def _asks(self, obs: dict[str, np.ndarray], action: dict[str, np.ndarray]) -> np.ndarray:
        """(B,) where this step asks for a deliberation besides every R steps: where the network hires or lets go."""
        return action["workforce"] != 0

    def _fork(self, rows: int):
        if rows not in self.forks:
            self.forks[rows] = self.belief.simulator(rows)
        return self.forks[rows]

    def _sampled_steps(self) -> int | None:
        """How far a future's arrivals are drawn: its H steps (None: to the episode's end)."""
        return self.H

    def _play(self, env_idx: np.ndarray, rows_k: list[int], first: dict[str, np.ndarray], t: int,
              rngs: list | None = None) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
        """Play one future per row: world ``rows_k[i]`` of environment ``env_idx[i]``, sampled from the belief.

        Each row plays ``first`` now, then the copy of the network (its memory of the episode
        so far, its noise ``rngs`` when given) for the rest of ``min(H, steps left)`` steps.
        Returns the NSW summed per row, the last observation and the steps played.
        """
        import torch

        n = len(env_idx)
        fork = self._fork(n)
        self.belief.sample_into(fork, env_idx, np.asarray(rows_k, dtype=np.int64), self._sampled_steps())
        p = self.player
        h, c = self.base._state  # after this step's act: the network's memory of the episode so far
        idx = torch.as_tensor(env_idx, device=h.device)
        p._state = (h[:, idx].clone(), c[:, idx].clone())
        p._starts = torch.zeros(1, n, device=h.device)
        if rngs is not None:
            p._rngs = rngs
        steps = min(self.H, self.horizon - t)
        total, fobs = fork.step_observe(first)
        for _ in range(steps - 1):
            r, fobs = fork.step_observe(p.act(fobs))
            total += r
        return total, fobs, steps

    def _decide(self, obs, envs: np.ndarray, action: dict[str, np.ndarray], t: int) -> None:
        w = action["workforce"]
        cands, rows_env, rows_a, rows_k = candidate_rows(envs, w, obs["workforce_mask"], self.K)
        n = len(rows_env)
        env_idx = np.asarray(rows_env, dtype=np.int64)
        rngs = [np.random.default_rng([int(self._seeds[e]), self.seed, PURPOSE_NOISE, t, k])
                for e, k in zip(rows_env, rows_k, strict=True)]
        first = {"dispatch": action["dispatch"][env_idx], "workforce": np.asarray(rows_a, dtype=np.int64),
                 "positioning": action["positioning"][env_idx]}
        total, _, _ = self._play(env_idx, rows_k, first, t, rngs)
        self.timing["decisions"] += len(envs)
        self.timing["rolls"] += n
        self.last_scores = pick_best(total, envs, cands, self.K, w, self.B)  # the network's action wins ties


__all__ = ["NetworkRollout"]
