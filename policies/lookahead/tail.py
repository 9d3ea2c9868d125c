"""The search's futures completed by a compiled composite instead of ended at the critic (issue #52).

Bertsekas' rollout ends a truncated future at a terminal cost; the search
(:mod:`wfbench.policies.lookahead.search`) takes it from PPO's critic, which misjudges one more
person on worlds it was not trained on (docs/policies.md, "Where it loses held out"), and the
played-out search (:mod:`~wfbench.policies.lookahead.playout`) drops it at ten times the cost.
:class:`TailSearch` takes the terminal cost from a cheap policy's play instead: each future is
the network's greedy play for H steps, then ``tail``, a compiled composite such as
``heuristic-tuned-train``, plays the rest of the episode on the same sampled world through the
OR rollouts' compiled roll-forward (microseconds a step), and the future scores the NSW summed
over all of it. The composite follows the real episode beside the network (it acts on every
observation, its actions unused), so a future's tail starts from its state at the deliberation.

Measured on the training split only and not a preset (docs/policies.md, "A compiled tail
instead of the critic"): the knobs stay for ``benchmarks/search_budget.py --knobs ...:tail=NAME``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.kernels.forward import RollBuffers, roll_forward
from wfbench.policies.lookahead.search import NetworkSearch
from wfbench.policies.protocol import as_obs


class TailSearch(NetworkSearch):
    """:class:`NetworkSearch` whose futures the composite ``tail`` plays to the end after H steps (module docstring).

    Args:
        base: the network the search plays (``policies.get("scalefree-general")``).
        tail: a compiled composite (``policies.get("heuristic-tuned-train")``).
        **knobs: as :class:`NetworkSearch` (``value`` is the tail's play, so it is not taken).
    """

    def __init__(self, base: Any, tail: Any, **knobs: Any):
        if "value" in knobs:
            raise ValueError("a tail search scores the rest of each future by its tail's play; allowed: no value knob")
        if not getattr(tail, "compiled", False):
            raise ValueError(f"search tail {getattr(tail, 'name', tail)!r} is not a composite of built-in kernels; "
                             "allowed: a compiled composite such as heuristic-tuned-train")
        super().__init__(base, value=(), **knobs)
        self.tail = tail
        self._tail: tuple | None = None  # per episode: the composite's codes, hyper-parameters, state, actions
        self._rows: dict[int, tuple] = {}  # rows -> the futures' copy of its state and the roll-forward's buffers
        self._MN = (0, 0)  # the world's facility and personnel slots

    def settings(self) -> dict[str, Any]:
        return {**super().settings(), "value": f"tail {getattr(self.tail, 'name', 'composite')}"}

    def reset(self, seeds) -> None:
        super().reset(seeds)
        self._tail = None

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        t = np.asarray(obs["t"], dtype=np.int64)
        B, M, N = obs["facilities"].shape[0], obs["facilities"].shape[1], obs["personnel"].shape[1]
        if self._tail is None or t[0] == 0:  # a new episode: the composite's plan and a fresh state
            codes, hp, state = self.tail.compiled_plan(self._seeds, M, N)
            self._tail = (codes, hp, state, (np.full((B, M), N, dtype=np.int64), np.zeros(B, dtype=np.int64),
                                             np.zeros((B, 2, M), dtype=np.float64)))
            self._rows = {}
            self._MN = (M, N)
        codes, hp, state, (d, w, p) = self._tail
        K.act_batch(as_obs(obs), state, codes, hp, d, w, p, t)  # its state follows the episode, through t
        return super().act(obs)

    def _sampled_steps(self) -> int | None:
        return None  # the tail plays to the episode's end

    def _play(self, env_idx: np.ndarray, rows_k: list[int], first: dict[str, np.ndarray], t: int,
              rngs: list | None = None) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
        """The network's H steps of each future (:meth:`NetworkRollout._play`), then the tail's play of the rest."""
        total, fobs, steps = super()._play(env_idx, rows_k, first, t, rngs)
        left = self.horizon - t - steps
        if left <= 0:
            return total, fobs, steps
        n = len(env_idx)
        codes, hp, state, _ = self._tail
        if n not in self._rows:
            self._rows[n] = (K.allocate_state(n, *self._MN), RollBuffers(n, *self._MN, onset_capacity=1))
        fstate, buffers = self._rows[n]
        for src, dst in zip(state, fstate, strict=True):
            np.take(src, env_idx, axis=0, out=dst[:n])
        rest = roll_forward(self._fork(n), left, codes, hp, fstate, buffers=buffers, rows=n, literal=True)[:n]
        return total + rest, fobs, steps


__all__ = ["TailSearch"]
