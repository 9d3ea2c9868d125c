"""The batched simulator: holds a trace batch and state and steps them with the compiled core.

``Simulator(scenario, seeds)`` runs ``len(seeds)`` independent episodes side by side.
Actions are a dict with the batched decision of each agent:

- ``"dispatch"``: (B, M) integers in ``0..N``; entry f names the person sent to
  facility slot f, ``N`` is the no-op;
- ``"workforce"``: (B,) integers in ``0..6``: 0 no-op, ``1 + l`` hire level l,
  ``4 + l`` let go a person of level l;
- ``"positioning"``: (B, 2, M) weights in [0, 1]; row 0 places a hire, row 1 picks
  who is let go (see ``docs/model.md``).

Malformed actions (wrong shape, out of range, NaN) raise :class:`ActionError` naming
the agent and the index; well-formed but impossible ones are ignored and counted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from wfbench.config import ScenarioConfig
from wfbench.dynamics import reset_batch, step_batch
from wfbench.observe import allocate_obs, observe_batch
from wfbench.state import COUNTERS, METRICS, N_WORKFORCE_ACTIONS, allocate, make_params
from wfbench.trace import trace_batch

AGENTS = ("dispatch", "workforce", "positioning")


class ActionError(ValueError):
    """A malformed action: wrong shape, out of range or not a number."""


def _first_bad(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def validate_actions(actions: dict, B: int, M: int, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check and convert a batched action dict; raise :class:`ActionError` on malformed input."""
    if not isinstance(actions, dict):
        raise ActionError(f"actions must be a dict with keys {AGENTS}, got {type(actions).__name__}")
    missing = [a for a in AGENTS if a not in actions]
    extra = [a for a in actions if a not in AGENTS]
    if missing or extra:
        raise ActionError(f"actions must have exactly the keys {AGENTS}; missing {missing}, unknown {extra}")

    def integers(agent: str, shape: tuple[int, ...], hi: int) -> np.ndarray:
        a = np.asarray(actions[agent])
        if a.shape != shape:
            raise ActionError(f"{agent} action has shape {a.shape}, expected {shape}")
        if a.dtype.kind not in "iub":
            if a.dtype.kind != "f":
                raise ActionError(f"{agent} action has dtype {a.dtype}; allowed: integers")
            bad = ~np.isfinite(a) | (a != np.round(a))
            if bad.any():
                idx = _first_bad(bad)
                raise ActionError(f"{agent} action: {a[idx].item()!r} at index {idx} is not an integer; allowed: integers 0..{hi}")
        out = a.astype(np.int64)
        bad = (out < 0) | (out > hi)
        if bad.any():
            idx = _first_bad(bad)
            raise ActionError(f"{agent} action: {out[idx]} at index {idx} is out of range; allowed: integers 0..{hi}")
        return np.ascontiguousarray(out)

    dispatch = integers("dispatch", (B, M), N)
    workforce = integers("workforce", (B,), N_WORKFORCE_ACTIONS - 1)
    pos = np.asarray(actions["positioning"])
    if pos.shape != (B, 2, M):
        raise ActionError(f"positioning action has shape {pos.shape}, expected {(B, 2, M)}")
    if pos.dtype.kind not in "fiub":
        raise ActionError(f"positioning action has dtype {pos.dtype}; allowed: numbers in [0, 1]")
    pos = pos.astype(np.float64)
    bad = ~np.isfinite(pos) | (pos < 0.0) | (pos > 1.0)
    if bad.any():
        idx = _first_bad(bad)
        raise ActionError(f"positioning action: {pos[idx].item()!r} at index {idx} is not allowed; allowed: numbers in [0, 1]")
    return dispatch, workforce, np.ascontiguousarray(pos)


class Simulator:
    """B independent episodes of one scenario, stepped together by the compiled core."""

    def __init__(self, scenario: str | ScenarioConfig, seeds: Sequence[int], keep_series: bool = True):
        self.config = ScenarioConfig.resolve(scenario)
        seeds = list(seeds)
        if not seeds:
            raise ValueError("seeds is empty; allowed: one or more integers >= 0")
        self.seeds = np.asarray(seeds, dtype=np.int64)
        self.trace = trace_batch(self.config, seeds)
        self.params = make_params(self.config)
        self.B = len(seeds)
        self.M = self.config.max_facilities
        self.N = self.config.max_personnel
        self.state = allocate(self.B, self.config, keep_series)
        self.obs_buffers = allocate_obs(self.B, self.M, self.N)
        self._reset_done = False

    # -- episode ------------------------------------------------------------------------------
    def reset(self) -> dict[str, np.ndarray]:
        reset_batch(self.state, self.trace, self.params)
        self._reset_done = True
        return self.observe()

    @property
    def t(self) -> int:
        return int(self.state.t[0])

    @property
    def done(self) -> bool:
        return self.t >= self.config.horizon

    def observe(self, with_masks: bool = True) -> dict[str, np.ndarray]:
        """The batched observation. Arrays are buffers overwritten by the next call: copy to keep."""
        observe_batch(self.state, self.params, self.obs_buffers, with_masks)
        obs = self.obs_buffers._asdict()
        obs["t"] = self.state.t
        return obs

    def step(self, actions: dict) -> np.ndarray:
        """Apply one batched action; returns the rewards (B,) of the step (NSW_t)."""
        if not self._reset_done:
            raise RuntimeError("call reset() before step()")
        if self.done:
            raise RuntimeError(f"the episode is over (horizon {self.config.horizon}); call reset()")
        d, w, p = validate_actions(actions, self.B, self.M, self.N)
        step_batch(self.state, self.trace, self.params, d, w, p)
        return self.state.last[:, METRICS.index("nsw")].copy()

    # -- results -----------------------------------------------------------------------------
    def counters(self, b: int | None = None) -> dict[str, np.ndarray]:
        c = self.state.counters if b is None else self.state.counters[b]
        return {name: c[..., i].copy() for i, name in enumerate(COUNTERS)}

    def episode_means(self) -> dict[str, np.ndarray]:
        """Mean of each per-step metric over the steps run so far, per environment."""
        steps = np.maximum(self.state.t, 1)[:, None]
        means = self.state.totals / steps
        return {name: means[:, i] for i, name in enumerate(METRICS)}
