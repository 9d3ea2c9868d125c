"""Training across worlds: several scenarios in one batch (domain randomization, docs/rl.md "Generalists").

``--scenarios`` names the worlds as every command does (:mod:`wfbench.scenarios.resolve`): a
suite's split (``suite-v1:train``), scenario names, or both; held-out scenarios are refused.
:class:`Worlds` puts one :class:`~wfbench.core.simulator.Simulator` per world behind the face of
one batched simulator: observations padded to the largest world's slots (empty slots masked),
actions split back per world, and a stratified deal of the ``B`` environments (:func:`deal`), each
reset onto fresh training seeds of its own world. The per-world reward normalization is the
collector's. Why stratified, and the padding: ``docs/rl.md``, "How a run spans several worlds".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wfbench.core.observe import allocate_obs
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import SEPARATOR, World
from wfbench.scenarios.resolve import resolve_worlds as resolve

__all__ = ["SEPARATOR", "World", "WorldSet", "Worlds", "deal", "resolve_worlds", "world_set"]

# the observation's arrays with a facility axis and with a personnel axis (axis 1), padded to the largest world's
FACILITY_KEYS = ("facilities", "facility_mask", "requesting")
PERSONNEL_KEYS = ("personnel", "personnel_mask", "personnel_status", "under_notice", "dispatchable")


@dataclass(frozen=True)
class WorldSet:
    """The worlds of a run trained across scenarios; a trainer's ``scenario`` when ``scenarios`` is set.

    ``name`` is the spec as given (what the checkpoint records as its scenario).
    """

    name: str
    worlds: tuple[World, ...]

    @property
    def names(self) -> list[str]:
        return [w.name for w in self.worlds]

    @property
    def slots(self) -> tuple[int, int]:
        """The facility and personnel slots of a batch that holds every world (the largest of each)."""
        return (max(w.config.max_facilities for w in self.worlds), max(w.config.max_personnel for w in self.worlds))


def world_set(spec: str) -> WorldSet:
    """The :class:`WorldSet` of a ``--scenarios`` spec (:func:`resolve_worlds`)."""
    return WorldSet(spec, tuple(resolve_worlds(spec)))


def resolve_worlds(spec: str) -> list[World]:
    """The worlds of a ``--scenarios`` spec to train on, in its order, each once.

    The one grammar of several worlds, :func:`wfbench.scenarios.resolve.resolve_worlds`,
    with a suite's held-out scenarios refused (a held-out scenario, the ``heldout`` split
    or a whole suite): only ``SUITE:train`` and training scenarios, named by their suite
    ids, or scenarios no suite holds.

    Raises:
        ValueError: an empty spec, an unknown suite split or scenario, a held-out one; the
            message names what is allowed.
    """
    return resolve(spec, heldout=False)


def deal(B: int, k: int) -> np.ndarray:
    """The environments of each of ``k`` worlds in a batch of ``B``: as even as possible, the first get more."""
    if B < k:
        raise ValueError(f"num_envs = {B} is smaller than the {k} worlds; allowed: num_envs >= {k}, so that every "
                         "world has an environment")
    return np.array([B // k + (i < B % k) for i in range(k)], dtype=np.int64)


class _State:
    """What a trainer reads of ``Simulator.state`` (``t``, ``last``), concatenated over the worlds."""

    def __init__(self, sims: Sequence[Simulator]):
        self._sims = sims

    @property
    def t(self) -> np.ndarray:
        return np.concatenate([s.state.t for s in self._sims])

    @property
    def last(self) -> np.ndarray:
        return np.concatenate([s.state.last for s in self._sims])


class Worlds:
    """The environments of several scenarios, stepped as one batch (the :class:`Simulator` methods a trainer uses).

    Args:
        worlds: the worlds, each with the seeds of its environments (``seeds[i]``).
        seeds: one list of seeds per world; the batch is the worlds' environments in order.
    """

    def __init__(self, worlds: Sequence[World], seeds: Sequence[Sequence[int]]):
        if len(worlds) != len(seeds):
            raise ValueError(f"{len(worlds)} worlds but {len(seeds)} seed lists")
        self.sims = [Simulator(w.config, s, keep_series=False, threads=1) for w, s in zip(worlds, seeds, strict=True)]
        sizes = np.array([s.B for s in self.sims], dtype=np.int64)
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        self.B = int(self.bounds[-1])
        self.M = max(s.M for s in self.sims)
        self.N = max(s.N for s in self.sims)
        self.world = np.repeat(np.arange(len(self.sims)), sizes)  # (B,) the world of each environment
        self.horizons = np.repeat([s.config.horizon for s in self.sims], sizes)
        self.state = _State(self.sims)
        self.obs_buffers = allocate_obs(self.B, self.M, self.N)

    @property
    def seeds(self) -> np.ndarray:
        return np.concatenate([s.seeds for s in self.sims])

    @property
    def dones(self) -> np.ndarray:
        return np.concatenate([s.dones for s in self.sims])

    def position(self) -> tuple[np.ndarray, np.ndarray]:
        """Each environment's index within its world and its world's size (the staggered cuts per world)."""
        sizes = np.diff(self.bounds)[self.world]
        return np.arange(self.B) - self.bounds[self.world], sizes

    def _padded(self, k: int, obs: dict[str, np.ndarray]) -> None:
        """Copy world ``k``'s observation into its rows of the batch's buffers, its missing slots empty."""
        lo, hi = self.bounds[k], self.bounds[k + 1]
        sim = self.sims[k]
        M, N = sim.M, sim.N
        for name, buf in self.obs_buffers._asdict().items():
            src = obs[name]
            if name == "dispatch_mask":  # (B, M, N + 1): the no-op column is the last of each
                buf[lo:hi, :M, :N] = src[:, :, :N]
                buf[lo:hi, :M, self.N] = src[:, :, N]
            elif name in FACILITY_KEYS:
                buf[lo:hi, :M] = src
            elif name in PERSONNEL_KEYS:
                buf[lo:hi, :N] = src
            else:
                buf[lo:hi] = src

    def _obs(self) -> dict[str, np.ndarray]:
        obs = self.obs_buffers._asdict()
        obs["t"] = self.state.t
        obs["world"] = np.concatenate([s.world_key(s.state.t) for s in self.sims])
        return obs

    def reset(self, indices=None, seeds=None) -> dict[str, np.ndarray]:
        """Reset every environment, or those at ``indices`` (of the batch) onto ``seeds``; the padded observation."""
        if indices is None:
            for k, sim in enumerate(self.sims):
                self._padded(k, sim.reset())
            return self._obs()
        idx = np.asarray(indices, dtype=np.int64)
        seeds = None if seeds is None else np.asarray(list(seeds), dtype=np.int64)
        for k, sim in enumerate(self.sims):
            lo, hi = self.bounds[k], self.bounds[k + 1]
            mine = (idx >= lo) & (idx < hi)
            if mine.any():
                obs = sim.reset(indices=idx[mine] - lo, seeds=None if seeds is None else seeds[mine].tolist())
                self._padded(k, obs)
        return self._obs()

    def step_observe(self, action: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Step each world with its rows of ``action``; the rewards (B,) and the padded observation."""
        rewards = []
        for k, sim in enumerate(self.sims):
            lo, hi = self.bounds[k], self.bounds[k + 1]
            part = {}
            if "dispatch" in action:
                d = action["dispatch"][lo:hi, :sim.M]
                part["dispatch"] = np.where(d >= sim.N, sim.N, d)  # the batch's no-op (N) is the world's
            if "workforce" in action:
                part["workforce"] = action["workforce"][lo:hi]
            if "positioning" in action:
                part["positioning"] = np.ascontiguousarray(action["positioning"][lo:hi, :, :sim.M])
            r, obs = sim.step_observe(part)
            rewards.append(r)
            self._padded(k, obs)
        return np.concatenate(rewards), self._obs()

    def episode_means(self) -> dict[str, np.ndarray]:
        means = [s.episode_means() for s in self.sims]
        return {k: np.concatenate([m[k] for m in means]) for k in means[0]}
