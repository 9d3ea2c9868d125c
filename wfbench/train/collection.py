"""Acting in the batched simulator on training seeds: the :class:`Collector` makes a rollout of T steps.

In the manner of Stable-Baselines3's ``collect_rollouts`` and TorchRL's ``SyncDataCollector``:
:func:`take_seeds` (the training seeds of a run), :func:`policy_step` (observation ->
tensors -> network -> sampled heads), and the collector, which fills preallocated tensors
with the shaped, normalized rewards (:class:`RunningStd`), resets finished episodes onto
fresh seeds and keeps their KPIs (:func:`episode_kpis`). PPO and IMPALA collect with it;
hindsight learning steps with :func:`policy_step` itself (``docs/rl.md``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_NAMES, SCORE
from wfbench.core.reward import step_reward
from wfbench.core.seeds import SEED_SETS
from wfbench.core.simulator import Simulator
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.dist import env_action, gumbel
from wfbench.train.config import ActorCriticConfig
from wfbench.train.precision import amp_dtype, autocast
from wfbench.train.worlds import Worlds, WorldSet, deal


def take_seeds(run_seed: int, cursor: int, k: int, index: int = 0, count: int = 1) -> list[int]:
    """``k`` seeds of the ``train`` set: a window per run seed, ``cursor`` seeds taken before (then onwards).

    Actor ``index`` of ``count`` takes every ``count``-th seed of the window from ``index``
    on, so ``count`` actors' seeds are disjoint and together are the window one would take.
    The caller adds ``k`` to its cursor.
    """
    train, n = SEED_SETS["train"], count
    start = (run_seed * 1_000_003 + cursor * n + index) % (len(train) - k * n)
    return list(train[start:start + k * n:n])


def policy_step(net, obs: dict, state, starts: torch.Tensor, model, gen: torch.Generator | None,
                amp: torch.dtype | bool | None) -> tuple[dict, dict, dict, tuple, dict]:
    """One step of the network on a batch (no grad): observation -> tensors -> forward -> sampled heads.

    ``model`` is the network ``net`` runs (``net`` may be its compiled wrapper); it says
    which observation it reads. ``gen`` draws the Gumbel noise of the sample (None:
    greedy), ``amp`` the autocast dtype (:func:`autocast`). Returns the raw tensors, the
    features, the head outputs, the LSTM state after the step and the actions.
    """
    dev = starts.device
    raw = scalefree.raw_tensors(model, obs, dev)
    x = scalefree.features(model, raw)
    with torch.no_grad(), autocast(dev, amp):
        out, state = net(x, state, starts[None])
    (B, M), N = obs["requesting"].shape, obs["personnel"].shape[1]
    shapes = scalefree.noise_shapes(model, B, M, N)
    noise = None if gen is None else {k: gumbel(s, gen, dev) for k, s in shapes.items()}
    return raw, x, out, state, scalefree.sample(model, out, x, noise)


def episode_kpis(sim: Simulator, which: np.ndarray | None = None) -> dict[str, float]:
    """The KPIs of the episodes in ``sim`` so far (``which`` environments; all by default), mean over them."""
    means = sim.episode_means()
    return {k: float(np.mean(means[k] if which is None else means[k][which])) for k in KPI_NAMES}


class RunningStd:
    """Running variance of the discounted return, by which rewards are divided (return normalization)."""

    def __init__(self):
        self.mean, self.var, self.count = 0.0, 1.0, 1e-4

    def update(self, x: np.ndarray) -> None:
        m, v, n = float(x.mean()), float(x.var()), x.size
        delta, total = m - self.mean, self.count + n
        self.mean += delta * n / total
        self.var = (self.var * self.count + v * n + delta**2 * self.count * n / total) / total
        self.count = total

    @property
    def std(self) -> float:
        return math.sqrt(self.var + 1e-8)


class Collector:
    """The batched simulator on training seeds and what acting in it needs: makes rollouts of T steps.

    ``cfg`` an :class:`ActorCriticConfig`; ``index`` of ``count`` collectors (IMPALA's Ray
    actors) takes its share of the training seeds (:func:`take_seeds`) and its own
    generator (seed ``cfg.seed + 1_000_003 * index``). ``reward`` a key of
    :data:`wfbench.core.reward.REWARDS`, shaped ``(r - reward_offset) * reward_scale`` and
    divided by the running std of the discounted return (``normalize_returns``).

    Episodes: with ``staggered`` environment b's first episode is cut after (b + 1) / B
    of the horizon; every environment whose episode ends is reset alone onto fresh
    training seeds (``Simulator.reset(indices, seeds)``), its LSTM state zeroed and its
    next step flagged as a start. With ``fresh_batches`` and no stagger the B episodes
    end together and a new Simulator is made on the next B seeds (with a fresh ``helper``,
    the heuristic parts of PPO's dispatch variant, which keep per-environment memory).
    ``amp``: the autocast dtype of the forward passes (:func:`amp_dtype`; ``"auto"``:
    from ``cfg.bf16`` and the device). ``num_envs``: the batch B of this collector (default
    ``cfg.num_envs``); ``stagger_across``: the ``count`` collectors' batches staggered as one
    (PPO's shards, :mod:`wfbench.train.shards`: environment b of collector ``index`` is
    ``index * B + b`` of ``count * B``, per world), not each alone (IMPALA's actors).
    """

    def __init__(self, cfg: ActorCriticConfig, scenario: ScenarioConfig, device: torch.device, *,
                 reward: str = "nsw", staggered: bool = True, fresh_batches: bool = False,
                 helper: Callable[[], Any] | None = None, index: int = 0, count: int = 1,
                 amp: str | torch.dtype | None = "auto", num_envs: int | None = None, stagger_across: bool = False):
        self.cfg, self.scenario, self.device, self.reward = cfg, scenario, device, reward
        self.amp = amp_dtype(device, cfg.bf16, amp)
        self.staggered, self.fresh_batches, self.make_helper = staggered, fresh_batches, helper
        self.index, self.count = index, count
        self.num_envs = cfg.num_envs if num_envs is None else num_envs
        self.stagger_across = stagger_across
        self.gen = torch.Generator(device=device).manual_seed(cfg.seed + 1_000_003 * index)
        self.ret_std = RunningStd()
        # several worlds (wfbench.train.worlds): a reward normalizer per world, and per world the running
        # mean of its step reward, which centres it (docs/rl.md, "Generalists")
        self.worlds = list(scenario.worlds) if isinstance(scenario, WorldSet) else None
        if self.worlds:
            self.world_std = [RunningStd() for _ in self.worlds]
            self.world_mean = [RunningStd() for _ in self.worlds]
        self.seed_cursor, self.episode, self.steps = 0, 0, 0
        self.timing = {"obs_to_tensor": 0.0, "forward": 0.0, "simulator": 0.0}
        self.sim = None

    def take_seeds(self, k: int) -> list[int]:
        seeds = take_seeds(self.cfg.seed, self.seed_cursor, k, self.index, self.count)
        self.seed_cursor += k
        return seeds

    def meta(self) -> dict:
        """What a checkpoint needs to resume the collector (its seeds, episode count, normalizer, generator)."""
        meta = {"seed_cursor": self.seed_cursor, "episode": self.episode, "ret_std": dict(vars(self.ret_std)),
                "generator": self.gen.get_state()}
        if self.worlds:
            meta["world_std"] = [dict(vars(r)) for r in self.world_std]
            meta["world_mean"] = [dict(vars(r)) for r in self.world_mean]
        return meta

    def restore(self, meta: dict) -> None:
        self.seed_cursor, self.episode = meta.get("seed_cursor", 0), meta["episode"]
        self.ret_std.__dict__.update(meta["ret_std"])
        if self.worlds:
            for mine, saved in zip(self.world_std + self.world_mean, meta["world_std"] + meta["world_mean"],
                                   strict=True):
                mine.__dict__.update(saved)
        self.gen.set_state(meta["generator"].cpu())  # a generator state is a CPU ByteTensor, on any device

    def start(self, model) -> None:
        """A fresh Simulator on the next B training seeds, a fresh LSTM state of ``model``."""
        if self.worlds:  # the environments dealt to the worlds, each its share of the batch's seeds
            seeds = self.take_seeds(self.num_envs)
            bounds = np.cumsum(deal(self.num_envs, len(self.worlds)))[:-1]
            self.sim = Worlds(self.worlds, [list(s) for s in np.split(np.asarray(seeds), bounds)])
            self.horizons = self.sim.horizons
            j, n = self.sim.position()  # staggered within each world
        else:
            self.sim = Simulator(self.scenario, self.take_seeds(self.num_envs), keep_series=False, threads=1)
            self.horizons = np.full(self.sim.B, self.scenario.horizon)
            j, n = np.arange(self.sim.B), self.sim.B
        if self.stagger_across:  # this collector's environments among the count collectors' together
            j, n = self.index * n + j, self.count * n
        self.obs = self.sim.reset()
        H, B = self.horizons, self.sim.B
        self.cut = (H * (j + 1)) // n if self.staggered else H.copy()
        self.helper = None
        if self.make_helper is not None:
            self.helper = self.make_helper()
            self.helper.reset(self.sim.seeds)
        self.state = model.initial_state(B, self.device)
        self.starts = torch.ones(B, device=self.device)
        self.ret = np.zeros(B)

    def _shaped(self, nsw: np.ndarray, ended: np.ndarray) -> np.ndarray:
        c = self.cfg
        if self.worlds:
            return self._shaped_worlds(step_reward(self.reward, nsw, self.sim.state.last), ended)
        reward = (step_reward(self.reward, nsw, self.sim.state.last) - c.reward_offset) * c.reward_scale
        if c.normalize_returns:
            self.ret = self.ret * c.gamma + reward
            self.ret_std.update(self.ret)
            reward = reward / self.ret_std.std
            self.ret[ended] = 0.0
        return reward

    def _shaped_worlds(self, raw: np.ndarray, ended: np.ndarray) -> np.ndarray:
        """Per world: the step reward minus the world's running mean, scaled, over the world's running return std.

        The worlds' welfare differs in level and in spread (``small``'s NSW is not
        ``table2-g256-f25-s5``'s); centring and scaling each by its own statistics keeps any
        one world from dominating the advantages and the value loss. ``reward_offset`` is
        not used: each world's own mean takes its place.
        """
        c, bounds = self.cfg, self.sim.bounds
        rows = [slice(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)]  # each world's, in the batch
        reward = np.empty_like(raw)
        for mine, mean in zip(rows, self.world_mean, strict=True):
            mean.update(raw[mine])
            reward[mine] = (raw[mine] - mean.mean) * c.reward_scale
        if c.normalize_returns:
            self.ret = self.ret * c.gamma + reward
            for mine, std in zip(rows, self.world_std, strict=True):
                std.update(self.ret[mine])
                reward[mine] /= std.std
            self.ret[ended] = 0.0
        return reward

    def _episode_ends(self, ended: np.ndarray, model, episodes: list[dict]) -> None:
        full = self.sim.dones  # whole episodes only in the logs (not the cut first ones)
        if full.any():
            kpis = episode_kpis(self.sim, full)
            if self.worlds:  # and the score of each world with a whole episode among them
                means = self.sim.episode_means()[SCORE]
                for k in np.unique(self.sim.world[full]):
                    kpis[f"{SCORE}/{self.worlds[k].name}"] = float(means[full & (self.sim.world == k)].mean())
            episodes.append(kpis)
        self.episode += int(ended.sum())
        if ended.all() and self.fresh_batches and not self.staggered:
            self.start(model)
            return
        idx = np.flatnonzero(ended)  # partial reset onto fresh training seeds
        self.obs = self.sim.reset(indices=idx, seeds=self.take_seeds(len(idx)))
        self.cut[idx] = self.horizons[idx]
        self.state = tuple(s * torch.as_tensor(~ended, dtype=s.dtype, device=self.device).view(1, -1, 1)
                           for s in self.state)

    @torch.no_grad()
    def collect(self, net, T: int, log_prob: Callable, values: Callable | None = None,
                model=None, keep_features: bool = False) -> dict[str, Any]:
        """A rollout of T steps of the B environments with ``net`` (sampled actions), in preallocated tensors.

        ``log_prob(out, x, acts)`` gives the behaviour log-probabilities of a step (B,) or
        (B, A); ``values(out)``, when given, the critic's values (B, A). ``model`` (default
        ``net``) makes the LSTM state of a fresh batch. Returns a dict: ``raw`` (T + 1, B, ...)
        per observation key and ``starts`` (T + 1, B) (the last: the observation after the
        rollout, for the bootstrap), ``dispatch``/``workforce``/``positioning`` (T, B, ...)
        int64 (zeros for a head the network lacks), ``logp``, ``value``, ``reward`` and
        ``done`` (T, B) float32 (done: the episode ended after the step), ``init_state``
        (the LSTM state before the first step) and ``episodes`` (the KPIs of the whole
        episodes that ended). ``keep_features``: also ``feats`` (T, B, ...) per key, the
        network's inputs of the T steps as the forward pass read them, so that a learner
        does not featurize ``raw`` again (the same bits: featurizing is row by row).
        """
        model = net if model is None else model
        if self.sim is None:
            self.start(model)
        dev, B, M = self.device, self.sim.B, self.sim.M
        acts_shape = {"dispatch": (M,), "workforce": (), "positioning": (2,)}
        roll: dict[str, Any] = {k: torch.zeros((T, B, *s), dtype=torch.long, device=dev) for k, s in acts_shape.items()}
        roll["starts"] = torch.empty((T + 1, B), device=dev)
        roll["reward"] = torch.empty((T, B), device=dev)
        roll["done"] = torch.empty((T, B), device=dev)
        roll["init_state"] = tuple(s.clone() for s in self.state)
        episodes: list[dict] = []
        for t in range(T):
            t0 = time.perf_counter()
            raw, x, out, self.state, acts = policy_step(net, self.obs, self.state, self.starts,
                                                        model, self.gen, self.amp)
            logp = log_prob(out, x, acts).float()
            if t == 0:  # the buffers of what the first step shows the shapes and types of
                roll["raw"] = {k: torch.empty((T + 1, *v.shape), dtype=v.dtype, device=dev) for k, v in raw.items()}
                roll["logp"] = torch.empty((T, *logp.shape), device=dev)
                if keep_features:
                    roll["feats"] = {k: torch.empty((T, *v.shape), dtype=v.dtype, device=dev) for k, v in x.items()}
                if values is not None:
                    roll["value"] = torch.empty((T, *values(out).shape), device=dev)
            action = env_action(acts, M)  # the dispatch variant's network has the dispatch head only
            t1 = time.perf_counter()
            if self.helper is not None:
                h = self.helper.act(self.obs)
                action["workforce"], action["positioning"] = h["workforce"], h["positioning"]
            for k, v in raw.items():
                roll["raw"][k][t] = v
            if keep_features:
                for k, v in x.items():
                    roll["feats"][k][t] = v
            roll["starts"][t] = self.starts
            for k, v in acts.items():
                roll[k][t] = v
            roll["logp"][t] = logp
            if values is not None:
                roll["value"][t] = values(out)
            nsw, self.obs = self.sim.step_observe(action)
            ended = self.sim.dones | (self.sim.state.t >= self.cut)  # (B,) episodes over after this step
            self.steps += B
            roll["reward"][t] = torch.as_tensor(self._shaped(nsw, ended), dtype=torch.float32, device=dev)
            roll["done"][t] = torch.as_tensor(ended, dtype=torch.float32, device=dev)
            if ended.any():
                self._episode_ends(ended, model, episodes)
            self.starts = torch.as_tensor(ended, dtype=torch.float32, device=dev)
            self.timing["forward"] += t1 - t0
            self.timing["simulator"] += time.perf_counter() - t1
        t0 = time.perf_counter()
        for k, v in scalefree.raw_tensors(model, self.obs, dev).items():
            roll["raw"][k][T] = v
        roll["starts"][T] = self.starts
        self.timing["obs_to_tensor"] += time.perf_counter() - t0
        roll["episodes"] = episodes
        return roll
