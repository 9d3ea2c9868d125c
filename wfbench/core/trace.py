"""The trace: every exogenous draw of one episode, a pure function of (config, seed).

:func:`trace` returns a :class:`Trace`: the initial facilities and workforce, every facility
arrival (a non-homogeneous Poisson process of rate ``churn_schedule(t) / churn_interval``, each
with its cell and an exponential lifetime of mean ``initial_facilities * churn_interval``), the
cells by the scenario's layout (:mod:`wfbench.core.layout`, drawn after the uniform draws so only
the cells differ between layouts), and ``key``, the key of the counter-based draws
(:mod:`wfbench.core.rng`) of failure clocks, repair outcomes and placements. Nothing depends on a
decision, so every policy meets the same world. Every draw: ``docs/model.md``, "Exogenous inputs".
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.rng import key_from_seed

NEVER = np.iinfo(np.int64).max // 4  # a time that never comes


class Trace(NamedTuple):
    """Exogenous draws for a batch of B episodes (a single trace has B = 1)."""

    seed: np.ndarray  # (B,) int64
    key: np.ndarray  # (B,) uint64
    fac0_active: np.ndarray  # (B, M) bool
    fac0_x: np.ndarray  # (B, M) int64
    fac0_y: np.ndarray  # (B, M) int64
    fac0_leave: np.ndarray  # (B, M) int64 exit step
    per0_active: np.ndarray  # (B, N) bool
    per0_x: np.ndarray  # (B, N) int64
    per0_y: np.ndarray  # (B, N) int64
    per0_level: np.ndarray  # (B, N) int64
    arr_t: np.ndarray  # (B, A) int64 arrival step (NEVER pads)
    arr_x: np.ndarray  # (B, A) int64
    arr_y: np.ndarray  # (B, A) int64
    arr_leave: np.ndarray  # (B, A) int64 exit step

    @property
    def batch_size(self) -> int:
        return int(self.seed.shape[0])

    def select(self, i: int) -> Trace:
        """The single-episode trace at batch index ``i`` (arrival padding kept)."""
        return Trace(*(a[i : i + 1] for a in self))


def _lifetimes(rng: np.random.Generator, n: int, mean: float) -> np.ndarray:
    return np.maximum(1, np.ceil(rng.exponential(mean, size=n))).astype(np.int64)


def trace(config: ScenarioConfig, seed: int) -> Trace:
    """All exogenous draws for ``seed`` (B = 1). Pure: same inputs, same arrays."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed = {seed!r} is not allowed; allowed: an integer >= 0")
    seed = int(seed)
    c = config
    M, N = c.max_facilities, c.max_personnel
    # spawn(4)'s first three children are spawn(3)'s: the uniform streams are what they always were
    fac_ss, per_ss, arr_ss, layout_ss = np.random.SeedSequence(seed).spawn(4)
    fac_rng, per_rng, arr_rng = (np.random.Generator(np.random.PCG64(s)) for s in (fac_ss, per_ss, arr_ss))
    life_mean = max(c.initial_facilities, 1) * c.churn_interval

    fac0_active = np.zeros(M, dtype=bool)
    fac0_active[: c.initial_facilities] = True
    fac0_x = fac_rng.integers(0, c.grid_width, size=M)
    fac0_y = fac_rng.integers(0, c.grid_height, size=M)
    fac0_leave = _lifetimes(fac_rng, M, life_mean)

    per0_active = np.zeros(N, dtype=bool)
    per0_active[: c.initial_personnel] = True
    per0_x = per_rng.integers(0, c.grid_width, size=N)
    per0_y = per_rng.integers(0, c.grid_height, size=N)
    per0_level = per_rng.choice(3, size=N, p=np.asarray(c.level_probs))

    # Arrivals at steps 1..horizon-1 by inverting the cumulative hazard.
    rate = c.churn_schedule.multipliers(c.horizon) / c.churn_interval
    rate[0] = 0.0
    cum = np.cumsum(rate[: c.horizon])
    total = float(cum[-1]) if c.horizon > 0 else 0.0
    n_guess = max(8, int(total + 6.0 * math.sqrt(total + 1.0) + 8))
    gaps = arr_rng.exponential(1.0, size=n_guess)
    while gaps.sum() <= total:  # astronomically rare: draw more, deterministically
        gaps = np.concatenate([gaps, arr_rng.exponential(1.0, size=n_guess)])
    points = np.cumsum(gaps)
    points = points[points <= total]
    arr_t = np.searchsorted(cum, points, side="left").astype(np.int64)
    A = arr_t.shape[0]
    arr_x = arr_rng.integers(0, c.grid_width, size=A)
    arr_y = arr_rng.integers(0, c.grid_height, size=A)
    arr_leave = arr_t + _lifetimes(arr_rng, A, life_mean)
    if c.layout.kind != "uniform":
        fac0_x, fac0_y, arr_x, arr_y = c.layout.draw(c.grid_width, c.grid_height, layout_ss, M, A)

    def one(a: np.ndarray, dtype=np.int64) -> np.ndarray:
        return np.asarray(a, dtype=dtype)[None]

    return Trace(
        seed=np.array([seed], dtype=np.int64),
        key=np.array([key_from_seed(seed, 0x5EED)], dtype=np.uint64),
        fac0_active=one(fac0_active, bool), fac0_x=one(fac0_x), fac0_y=one(fac0_y), fac0_leave=one(fac0_leave),
        per0_active=one(per0_active, bool), per0_x=one(per0_x), per0_y=one(per0_y), per0_level=one(per0_level),
        arr_t=one(arr_t), arr_x=one(arr_x), arr_y=one(arr_y), arr_leave=one(arr_leave),
    )


def stack(traces: list[Trace]) -> Trace:
    """One batch from single traces; arrival lists are padded with ``NEVER``."""
    if not traces:
        raise ValueError("stack() needs at least one trace")
    A = max(1, max(t.arr_t.shape[1] for t in traces))

    def pad(a: np.ndarray, fill: int) -> np.ndarray:
        out = np.full((a.shape[0], A), fill, dtype=a.dtype)
        out[:, : a.shape[1]] = a
        return out

    parts = []
    for t in traces:
        parts.append(t._replace(arr_t=pad(t.arr_t, NEVER), arr_x=pad(t.arr_x, 0), arr_y=pad(t.arr_y, 0),
                                arr_leave=pad(t.arr_leave, NEVER)))
    return Trace(*(np.ascontiguousarray(np.concatenate(cols)) for cols in zip(*parts, strict=True)))


def trace_batch(config: ScenarioConfig, seeds) -> Trace:
    """The stacked traces of ``seeds`` (a sequence of integers >= 0)."""
    seeds = [int(s) if isinstance(s, (int, np.integer)) and not isinstance(s, bool) else s for s in seeds]
    return stack([trace(config, s) for s in seeds])
