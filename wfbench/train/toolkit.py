"""What the trainers (ppo, impala, hindsight) share: one toolkit of data structures and functions.

In the manner of Stable-Baselines3's ``RolloutBuffer``/``collect_rollouts`` and TorchRL's
``SyncDataCollector``: plain pieces an algorithm file calls, top to bottom, no hooks.

- Settings: :class:`BaseConfig` (scenario, network, device, seeds, evaluation and
  checkpoint settings; its checks and ``from_dict``) and :class:`ActorCriticConfig` on
  it (the reward shaping and loss coefficients PPO and IMPALA share). Each algorithm's
  config subclasses one of them and adds only its own fields and checks (``check``).
- Acting: :func:`take_seeds` (the training seeds of a run), :func:`autocast`,
  :func:`policy_step` (observation -> tensors -> network -> sampled heads) and
  :class:`Collector`, which steps the batched simulator and fills preallocated tensors:
  a rollout of T steps with the shaped, normalized rewards, episode ends with partial
  reset onto fresh training seeds and the LSTM state reset, the finished episodes' KPIs.
- A run: :func:`start_run` (checks, threads, torch seed; the :class:`Run` record every
  trainer holds as ``run``: its config, device, scenario, folder, progress and cost),
  :func:`init_weights` (``init``), :class:`RunOutputs` (TensorBoard, progress bar,
  ``best.pt``, checkpoints, Ctrl-C), :func:`run_checkpoint` (the keys every checkpoint
  has, ``algo`` among them), :func:`save_run` / :func:`load_run` (the shared resume
  state: optimizer, torch's random state, counters, history), :func:`score_public`.

A checkpoint of any trainer loads as a policy by its algorithm (``impala:PATH``,
``hindsight:PATH``, ``ppo:PATH``; ``ppo:`` loads any, :mod:`wfbench.policies.registry`) because
all three write the keys of :func:`run_checkpoint`; each adds what its own resume needs.
Checkpoints are selected on the public seeds only (:func:`score_public`).
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch

from wfbench import policies
from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_NAMES, SCORE
from wfbench.core.reward import step_reward
from wfbench.core.seeds import SEED_SETS, resolve_seeds
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import training_hardware
from wfbench.harness.evaluation import evaluate
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.dist import env_action, gumbel
from wfbench.policies.neural.model import AgentSet, WorkforceNet, count_parameters, model_config
from wfbench.policies.neural.policy import NetworkPolicy, load_checkpoint
from wfbench.scenarios.score import normalize
from wfbench.train.worlds import Worlds, WorldSet, deal, world_set

DECISIONS = ("dispatch", "workforce", "positioning")  # the heads of the joint network, in the simulator's order
DEVICES = ("auto", "cpu", "cuda")


# -- settings -------------------------------------------------------------------------------------
def check_ints(cfg, names: Sequence[str], least: int = 1) -> None:
    """Each of ``names`` an integer (not a bool) >= ``least``, else a ValueError naming what is allowed."""
    for name in names:
        v = getattr(cfg, name)
        if type(v) is not int or v < least:
            raise ValueError(f"{name} = {v!r} is not allowed; allowed: an integer >= {least}")


def check_numbers(cfg, names: Sequence[str], ok: Callable[[float], bool], allowed: str) -> None:
    """Each of ``names`` passes ``ok``, else a ValueError: ``NAME = V is not allowed; allowed: ALLOWED``."""
    for name in names:
        if not ok(getattr(cfg, name)):
            raise ValueError(f"{name} = {getattr(cfg, name)!r} is not allowed; allowed: {allowed}")


@dataclass
class BaseConfig:
    """The settings every trainer has; saved as ``config.json`` in the run directory and in each checkpoint.

    An algorithm's config subclasses it (or :class:`ActorCriticConfig`), adds its own
    fields (and may give a field another default) and its own checks in :meth:`check`.
    """

    scenario: str = "paper-64"
    scenarios: str = ""  # several worlds (wfbench.train.worlds): e.g. "suite-v1:train"; when set, scenario is unused
    variant: str = "joint"
    model: str = "small"  # wfbench.policies.neural.model.PRESETS
    steps: int = 1_000_000  # environment steps in all (B per simulator step)
    num_envs: int = 32  # B
    num_steps: int = 32  # T: steps per rollout (or stored sequence)
    seed: int = 0
    device: str = "auto"  # auto | cpu | cuda
    bf16: bool = True  # CUDA only: bf16 autocast of the forward passes
    threads: int = 1  # torch CPU threads (the simulator uses numba's)
    checkpoint_every: int = 20  # updates (iterations)
    eval_every: int = 20  # updates (iterations); 0: never
    eval_seeds: str = "public:10"  # a part of the public set: checkpoint selection only
    run_dir: str = "runs/ppo"
    init: str = ""  # a checkpoint whose network weights start this run (fine-tuning); nothing else is taken
    model_overrides: dict = field(default_factory=dict)
    scalefree_ok = False  # a class attribute, not a setting: whether this trainer trains the scale-free network

    def validate(self) -> ScenarioConfig | WorldSet:
        """The shared checks, the algorithm's (:meth:`check`), then the network's config (a bad preset says so).

        Returns:
            The scenario, resolved (once: :func:`start_run` keeps it), or the :class:`WorldSet` of ``scenarios``.
        """
        if self.device not in DEVICES:
            raise ValueError(f"device {self.device!r} is not allowed; allowed: {', '.join(DEVICES)}")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device 'cuda' asked for, but torch sees no CUDA device (use --device cpu or auto)")
        check_ints(self, ("steps", "num_envs", "num_steps", "threads", "checkpoint_every"))
        check_ints(self, ("eval_every",), least=0)
        if self.model == scalefree.ARCH and not self.scalefree_ok:
            raise ValueError(f"model 'scalefree' is not trained by {type(self).__module__.rsplit('.', 1)[-1]}; "
                             "allowed: --algo ppo or impala (or a model preset: tiny, small, paper, cpu)")
        self.check()
        if self.scenarios:
            scenario = world_set(self.scenarios)
            if self.variant != "joint":
                raise ValueError(f"scenarios {self.scenarios!r} with variant {self.variant!r}: training across worlds "
                                 "is for the joint network; allowed: variant joint")
        else:
            scenario = ScenarioConfig.resolve(self.scenario)
        if not set(resolve_seeds(self.eval_seeds)) <= set(SEED_SETS["public"]):
            raise ValueError(f"eval_seeds {self.eval_seeds!r}: checkpoints are selected on the public seeds "
                             "(1000-1049) only, never on test seeds")
        self.network_config()
        return scenario

    def check(self) -> None:
        """The algorithm's own checks (a subclass's); ValueError names what is allowed."""

    def network_config(self):
        """The network's config: the joint network with all three heads (PPO's variants and agents differ)."""
        return network_config(self.model, DECISIONS, self.model_overrides)

    @classmethod
    def from_dict(cls, d: dict):
        """The config of a saved ``train_config`` (keys this class does not have are dropped)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


@dataclass
class ActorCriticConfig(BaseConfig):
    """The settings PPO and IMPALA share: the :class:`Collector`'s reward shaping, and the loss coefficients."""

    lr: float = 3e-4
    gamma: float = 0.995
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    reward_offset: float = 0.7  # reward = (NSW_t - offset) * scale
    reward_scale: float = 10.0
    normalize_returns: bool = True  # rewards divided by a running std of the discounted return
    stagger: bool = True  # staggered episodes by partial reset

    def validate(self) -> ScenarioConfig | WorldSet:
        check_numbers(self, ("gamma",), lambda v: 0.0 < v <= 1.0, "a number in (0, 1]")
        check_numbers(self, ("lr", "max_grad_norm"), lambda v: v > 0.0, "a number > 0")
        check_numbers(self, ("ent_coef", "vf_coef", "reward_scale"), lambda v: v >= 0.0, "a number >= 0")
        return super().validate()


# -- acting ---------------------------------------------------------------------------------------
def take_seeds(run_seed: int, cursor: int, k: int, index: int = 0, count: int = 1) -> list[int]:
    """``k`` seeds of the ``train`` set: a window per run seed, ``cursor`` seeds taken before (then onwards).

    Actor ``index`` of ``count`` takes every ``count``-th seed of the window from ``index``
    on, so ``count`` actors' seeds are disjoint and together are the window one would take.
    The caller adds ``k`` to its cursor.
    """
    train, n = SEED_SETS["train"], count
    start = (run_seed * 1_000_003 + cursor * n + index) % (len(train) - k * n)
    return list(train[start:start + k * n:n])


AMP_DTYPES = {"bfloat16": torch.bfloat16, "float16": torch.float16}


def amp_dtype(device: torch.device, bf16: bool, amp: str | torch.dtype | None = "auto") -> torch.dtype | None:
    """The autocast dtype of a run's forward passes; None: float32 (no autocast).

    ``amp="auto"`` (what ``wfbench train`` uses): bfloat16 on CUDA when ``bf16``, float32
    on CPU. Otherwise ``amp`` is the dtype itself (``torch.bfloat16``, ``torch.float16``
    or their names) on whatever device the run is, CPU included, or None for float32:
    the CPU tests run the trainers' CUDA dtype path this way (``torch.autocast("cpu", ...)``,
    tests/train/test_amp.py).
    """
    if isinstance(amp, str):
        if amp == "auto":
            return torch.bfloat16 if device.type == "cuda" and bf16 else None
        if amp not in AMP_DTYPES:
            raise ValueError(f"amp {amp!r} is not allowed; allowed: auto, {', '.join(AMP_DTYPES)}")
        return AMP_DTYPES[amp]
    if amp is not None and amp not in AMP_DTYPES.values():
        raise ValueError(f"amp {amp!r} is not allowed; allowed: auto, None, {', '.join(AMP_DTYPES)}")
    return amp


def autocast(device: torch.device, amp: torch.dtype | bool | None):
    """Autocast of a forward pass in dtype ``amp`` on ``device``'s type; None: a no-op context (float32).

    ``amp`` is a run's :func:`amp_dtype` (``Run.amp``); a bool is the older ``bf16`` flag
    (bfloat16 on CUDA only). The network keeps its heads in float32 either way.
    """
    if isinstance(amp, bool):
        amp = amp_dtype(device, amp)
    return torch.autocast(device_type=device.type, dtype=amp or torch.bfloat16, enabled=amp is not None)


def network_config(preset: str, decisions: tuple[str, ...], overrides: dict):
    """The config of network ``preset``: one of :data:`wfbench.policies.neural.model.PRESETS` or ``scalefree``."""
    if preset == scalefree.ARCH:
        return scalefree.scalefree_config(decisions, **overrides)
    return model_config(preset, decisions, **overrides)


def build_model(network, independent: bool = False) -> torch.nn.Module:
    """A fresh network (on CPU) for a run's config (:func:`network_config`).

    The scale-free network for an observation-version-2 config (``ScaleFreeConfig``), else the
    paper's: ``AgentSet`` (one network per decision) when ``independent``, ``WorkforceNet``
    otherwise.
    """
    if getattr(network, "obs_version", 1) == 2:
        return scalefree.ScaleFreeNet(network)
    return AgentSet(network) if independent else WorkforceNet(network)


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
    from ``cfg.bf16`` and the device).
    """

    def __init__(self, cfg: ActorCriticConfig, scenario: ScenarioConfig, device: torch.device, *,
                 reward: str = "nsw", staggered: bool = True, fresh_batches: bool = False,
                 helper: Callable[[], Any] | None = None, index: int = 0, count: int = 1,
                 amp: str | torch.dtype | None = "auto"):
        self.cfg, self.scenario, self.device, self.reward = cfg, scenario, device, reward
        self.amp = amp_dtype(device, cfg.bf16, amp)
        self.staggered, self.fresh_batches, self.make_helper = staggered, fresh_batches, helper
        self.index, self.count = index, count
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
            seeds = self.take_seeds(self.cfg.num_envs)
            bounds = np.cumsum(deal(self.cfg.num_envs, len(self.worlds)))[:-1]
            self.sim = Worlds(self.worlds, [list(s) for s in np.split(np.asarray(seeds), bounds)])
            self.horizons = self.sim.horizons
            j, n = self.sim.position()  # staggered within each world
        else:
            self.sim = Simulator(self.scenario, self.take_seeds(self.cfg.num_envs), keep_series=False, threads=1)
            self.horizons = np.full(self.sim.B, self.scenario.horizon)
            j, n = np.arange(self.sim.B), self.sim.B
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
                model=None) -> dict[str, Any]:
        """A rollout of T steps of the B environments with ``net`` (sampled actions), in preallocated tensors.

        ``log_prob(out, x, acts)`` gives the behaviour log-probabilities of a step (B,) or
        (B, A); ``values(out)``, when given, the critic's values (B, A). ``model`` (default
        ``net``) makes the LSTM state of a fresh batch. Returns a dict: ``raw`` (T + 1, B, ...)
        per observation key and ``starts`` (T + 1, B) (the last: the observation after the
        rollout, for the bootstrap), ``dispatch``/``workforce``/``positioning`` (T, B, ...)
        int64 (zeros for a head the network lacks), ``logp``, ``value``, ``reward`` and
        ``done`` (T, B) float32 (done: the episode ended after the step), ``init_state``
        (the LSTM state before the first step) and ``episodes`` (the KPIs of the whole
        episodes that ended).
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
                if values is not None:
                    roll["value"] = torch.empty((T, *values(out).shape), device=dev)
            action = env_action(acts, M)  # the dispatch variant's network has the dispatch head only
            t1 = time.perf_counter()
            if self.helper is not None:
                h = self.helper.act(self.obs)
                action["workforce"], action["positioning"] = h["workforce"], h["positioning"]
            for k, v in raw.items():
                roll["raw"][k][t] = v
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


# -- a run ----------------------------------------------------------------------------------------
@dataclass
class Run:
    """The record of a training run that every trainer holds as ``run`` (:func:`start_run` makes it).

    Fixed at the start: ``config``, ``device``, ``scenario`` (a ScenarioConfig, or a
    WorldSet across worlds), ``network`` (the network's config), ``dir`` (the run folder),
    ``progress`` and ``log`` (progress bar, TensorBoard). The run's progress, saved in every
    checkpoint and restored by :func:`load_run`: ``global_step`` (environment steps),
    ``best`` (the best public score and where it was reached, :meth:`RunOutputs.public`) and
    ``history`` (the public scores). Its provenance and cost: ``commit`` (the code the run
    started from; a resumed run keeps its first), ``hardware`` (of each segment),
    ``wall_before`` (seconds of the earlier segments of a resumed run; None when its
    checkpoint did not record them) and ``wall_start`` (``time.monotonic()`` when this
    segment started). ``amp``: the autocast dtype of its forward passes (None: float32;
    :func:`amp_dtype`).
    """

    config: BaseConfig
    device: torch.device
    scenario: ScenarioConfig | WorldSet
    network: Any
    dir: Path
    progress: bool
    log: bool
    commit: str
    hardware: str
    wall_before: float | None = 0.0
    wall_start: float = field(default_factory=time.monotonic)
    best: dict = field(default_factory=lambda: {"score": -math.inf, "update": None})
    history: list = field(default_factory=list)
    global_step: int = 0
    amp: torch.dtype | None = None

    @property
    def cuda(self) -> bool:
        """Whether the run is on a CUDA device."""
        return self.device.type == "cuda"


def start_run(config: BaseConfig, progress: bool, log: bool, amp: str | torch.dtype | None = "auto") -> Run:
    """Check ``config``, set torch's threads and seed; the :class:`Run` record of a fresh run on it.

    ``amp``: the autocast dtype of the run's forward passes (:func:`amp_dtype`; ``"auto"``:
    bfloat16 on CUDA with ``config.bf16``, float32 on CPU).
    """
    # resolved once, by the check; several worlds (``scenarios``): a WorldSet, which the collector, the public
    # scores and the checkpoint read
    scenario = config.validate()
    device = torch_device(config.device)
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    return Run(config=config, device=device, scenario=scenario, network=config.network_config(),
               dir=Path(config.run_dir), progress=progress, log=log, commit=git_commit(),
               hardware=training_hardware(device), amp=amp_dtype(device, config.bf16, amp))


def init_weights(trainer) -> None:
    """``init``: the network weights of another checkpoint start this run (its network must be this run's)."""
    run = trainer.run
    c = run.config
    start = load_checkpoint(c.init, str(run.device))
    if start["model_config"] != run.network.to_dict():
        agents = f", --agents {c.agents}" if hasattr(c, "agents") else ""
        raise ValueError(f"--init {c.init!r}: its network ({start['model_config']}) is not this run's "
                         f"(--model {c.model}, --variant {c.variant}{agents})")
    trainer.model.load_state_dict(start["model"])


def run_checkpoint(trainer, algo: str, count: int, **fields) -> dict:
    """The keys every checkpoint has (what ``ALGO:PATH`` and ``ppo:PATH`` load), plus ``fields``.

    ``algo`` names the trainer (:data:`wfbench.train.registry.ALGORITHMS`); ``count`` its
    updates (iterations), saved as ``update``. ``train_wall_s`` (wall seconds of training
    so far, over every segment of a resumed run) and ``train_hardware`` (the CPU, cores
    and GPU of each segment) are the run's cost, which the leaderboard shows beside
    ``global_step``, the env-steps (:func:`wfbench.harness.budget.policy_budget`).
    """
    run = trainer.run
    cost: dict[str, Any] = {"train_hardware": run.hardware}
    if run.wall_before is not None:  # None: resumed from a checkpoint that did not record its wall time
        cost["train_wall_s"] = run.wall_before + time.monotonic() - run.wall_start
    return {
        "model": {k: v.detach().cpu() for k, v in trainer.model.state_dict().items()},
        "model_config": run.network.to_dict(),
        "obs_version": getattr(run.network, "obs_version", 1),  # the observation it reads (core.observation_v2)
        "algo": algo,
        "variant": run.config.variant,
        "scenario": run.scenario.name,
        **({"worlds": run.scenario.names} if isinstance(run.scenario, WorldSet) else {}),
        "train_config": asdict(run.config),
        "update": count,
        "global_step": run.global_step,
        "git_commit": run.commit,
        "best": run.best,
        "history": run.history,
        **cost,
        **fields,
    }


def save_run(trainer, path: Path, full: bool, **resume) -> Path:
    """``trainer.checkpoint()`` at ``path``; ``full`` adds what a resume needs.

    That is the optimizer, torch's random state and the trainer's own ``resume`` entries.
    """
    ckpt = trainer.checkpoint()
    if full:
        ckpt["optimizer"] = trainer.opt.state_dict()
        ckpt["torch_rng"] = torch.get_rng_state()
        ckpt.update(resume)
    return save_atomic(ckpt, path)


def load_run(trainer, path, algo: str) -> dict:
    """Resume the shared state of a full checkpoint of ``algo``: weights, optimizer, torch's random state, history.

    Returns the checkpoint (the trainer takes its counters and its own state from it).
    """
    t, run = trainer, trainer.run
    ckpt = load_checkpoint(path, str(run.device))
    if "optimizer" not in ckpt:
        raise ValueError(f"checkpoint {str(path)!r} has no optimizer state: it cannot be resumed (a best.pt? "
                         "resume from latest.pt or checkpoints/*)")
    if ckpt.get("algo", "ppo") != algo:
        raise ValueError(f"checkpoint {str(path)!r} is not a {algo} run (algo {ckpt.get('algo', 'ppo')!r})")
    if ckpt["model_config"] != run.network.to_dict() or ckpt["variant"] != run.config.variant:
        raise ValueError(f"checkpoint {str(path)!r} is a {ckpt['variant']} run of another model; resume with the "
                         "settings of its config.json")
    t.model.load_state_dict(ckpt["model"])
    t.opt.load_state_dict(ckpt["optimizer"])
    torch.set_rng_state(ckpt["torch_rng"].cpu())
    run.global_step = ckpt["global_step"]
    run.commit = ckpt.get("git_commit", run.commit)
    run.best, run.history = ckpt["best"], ckpt["history"]
    # the cost of the segments before this one (a checkpoint from before wfbench saved it: not recorded)
    run.wall_before = float(ckpt["train_wall_s"]) if "train_wall_s" in ckpt else None
    run.wall_start = time.monotonic()
    before = ckpt.get("train_hardware", "not recorded")
    if before != run.hardware:
        run.hardware = f"{before}; then {run.hardware}"
    return ckpt


def score_public(policy: Callable[[str], Any], scenario, eval_seeds: str) -> dict:
    """Mean NSW and workforce cost on the public selection seeds, sampled and greedy (the score is the sampled one).

    ``policy(mode)`` gives the deployable policy in ``mode`` (``"sample"`` or ``"greedy"``).
    """
    seeds = resolve_seeds(eval_seeds)
    if isinstance(scenario, WorldSet):
        return score_worlds(policy, scenario, seeds)
    res: dict = {}
    for mode in ("sample", "greedy"):
        df = evaluate(policy(mode), scenario, seeds, backend="serial", act_timeout_s=None)
        res[mode] = float(df["nsw"].mean())
        res[f"{mode}_workforce_cost"] = float(df["workforce_cost"].mean())
    res["seeds"] = seeds
    return res


def score_worlds(policy: Callable[[str], Any], worlds: WorldSet, seeds: list[int]) -> dict:
    """A run across worlds: the sampled policy on the public seeds of every world; the score is their mean.

    Each world's mean NSW is put on the suite's normalized scale (``(NSW - random) /
    (bound - random)``, :func:`wfbench.scenarios.normalize`, the published constants of the
    world's suite id) when every world has constants, so that no world counts more because
    its NSW spreads more; otherwise the score is the mean NSW over the worlds. The
    constants are fixed numbers per scenario: no test-seed result of the policy enters.
    Greedy decisions are not scored (one mode, to halve the cost of scoring eight worlds).
    """
    nsw, cost = {}, {}
    for w in worlds.worlds:
        df = evaluate(policy("sample"), w.config, seeds, backend="serial", act_timeout_s=None)
        nsw[w.name], cost[w.name] = float(df["nsw"].mean()), float(df["workforce_cost"].mean())
    try:
        per_world = {name: float(normalize(v, name)) for name, v in nsw.items()}
        scale = "normalized"
    except ValueError:  # a world no suite has constants for: the plain mean NSW
        per_world, scale = dict(nsw), "nsw"
    return {"sample": float(np.mean(list(per_world.values()))), "greedy": None, "scale": scale,
            "worlds": per_world, "nsw_worlds": nsw,
            "sample_workforce_cost": float(np.mean(list(cost.values()))), "seeds": seeds}


def log_public(writer, res: dict, step: int) -> None:
    """The TensorBoard scalars of a :func:`score_public` result (``public/*``; across worlds, one per world too)."""
    writer.add_scalar("public/nsw_sample" if res.get("scale", "nsw") == "nsw" else "public/score_sample",
                      res["sample"], step)
    if res["greedy"] is not None:
        writer.add_scalar("public/nsw_greedy", res["greedy"], step)
    writer.add_scalar("public/workforce_cost_sample", res["sample_workforce_cost"], step)
    for name, v in res.get("worlds", {}).items():
        writer.add_scalar(f"public/{name}", v, step)


class RunOutputs:
    """What the three trainers' loops write besides learning: the loop's scaffolding in one place.

    ``with RunOutputs(trainer, unit, desc, total, initial) as out:`` opens the TensorBoard
    writer (``RUN/tb``, when ``trainer.run.log``) and the progress bar (when ``trainer.run.progress``;
    ``initial`` of ``total`` environment steps done). Inside, the loop calls
    :meth:`scalars`, :meth:`public` (after scoring the public seeds: logs the score and keeps
    ``best.pt``), :meth:`checkpoint` and :meth:`advance`. Leaving the block saves
    ``latest.pt``; Ctrl-C saves it too, says how to resume and re-raises. ``unit`` names the
    trainer's counter attribute (``"update"`` or ``"iteration"``) for that message.
    ``cleanup`` (IMPALA: stop the actors) runs however the block is left: after the save
    on Ctrl-C, before it on a normal exit, so neither waits on the other going wrong.
    """

    def __init__(self, trainer, unit: str, desc: str, total: int, initial: int,
                 cleanup: Callable[[], None] | None = None):
        self.trainer, self.unit, self.cleanup = trainer, unit, cleanup
        self.writer = self.bar = None
        self.last_nsw: float | None = None  # of the last finished training episode, shown on the bar
        if trainer.run.log:
            from torch.utils.tensorboard import SummaryWriter

            self.writer = SummaryWriter(str(trainer.run.dir / "tb"))
        if trainer.run.progress:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="step", unit_scale=True, desc=desc)

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        t = self.trainer
        latest = t.run.dir / "latest.pt"
        try:
            if exc_type is KeyboardInterrupt:
                t.save(latest)
                if self.bar:
                    self.bar.close()
                print(f"interrupted: checkpoint saved to {latest} ({self.unit} {getattr(t, self.unit)}); "
                      f"continue with --resume {latest}")
        finally:
            try:
                if self.cleanup:
                    self.cleanup()
            finally:
                if self.writer:
                    self.writer.close()
        if exc_type is None:
            if self.bar:
                self.bar.close()
            t.save(latest)

    def scalars(self, prefix: str, values: dict, keys=None) -> None:
        """TensorBoard ``prefix/key`` for each of ``keys`` (default: all) present in ``values``, at the global step."""
        if self.writer:
            for k in values if keys is None else [k for k in keys if k in values]:
                self.writer.add_scalar(f"{prefix}/{k}", values[k], self.trainer.run.global_step)

    def episodes(self, episodes: list[dict]) -> None:
        """The finished training episodes' KPIs (``episode/*``)."""
        for ep in episodes:
            self.scalars("episode", ep)
            self.last_nsw = ep[SCORE]

    def public(self, res: dict, count: int) -> None:
        """Log a :func:`score_public` result; keep ``best.pt`` (the policy only) when its sampled score is the best."""
        t, run = self.trainer, self.trainer.run
        if self.writer:
            log_public(self.writer, res, run.global_step)
        if res["sample"] > run.best["score"]:
            run.best = {"score": res["sample"], "update": count, "global_step": run.global_step, "mode": "sample",
                        "seeds": res["seeds"], "greedy": res["greedy"]}
            t.save(run.dir / "best.pt", full=False)

    def after_update(self, count: int) -> None:
        """PPO's and IMPALA's end of update ``count``: evaluation and checkpoints when they are due.

        Every ``eval_every`` updates score the public seeds (a history row, ``best.pt``),
        every ``checkpoint_every`` save ``checkpoints/update_<count>.pt`` and ``latest.pt``.
        """
        t, run = self.trainer, self.trainer.run
        if run.config.eval_every and count % run.config.eval_every == 0:
            res = t.evaluate_public()
            run.history.append({"update": count, "global_step": run.global_step, **res})
            self.public(res, count)
        if count % run.config.checkpoint_every == 0:
            self.checkpoint(f"update_{count:06d}.pt")

    def checkpoint(self, name: str) -> None:
        """``checkpoints/NAME`` and ``latest.pt``, both resumable."""
        self.trainer.save(self.trainer.run.dir / "checkpoints" / name)
        self.trainer.save(self.trainer.run.dir / "latest.pt")

    def advance(self, steps: int, postfix: dict) -> None:
        """Move the progress bar by ``steps``; ``postfix``, the last training episode's NSW, the best public score."""
        if self.bar:
            self.bar.update(steps)
            postfix = dict(postfix)
            if self.last_nsw is not None:
                postfix["ep_nsw"] = f"{self.last_nsw:.3f}"
            if self.trainer.run.best["update"] is not None:
                postfix["public"] = f"{self.trainer.run.best['score']:.3f}"
            self.bar.set_postfix(postfix)


def save_unselected_best(trainer) -> Path | None:
    """``RUN/best.pt`` = the last weights when no evaluation selected one (``--eval-every 0``, or a run too short).

    :func:`wfbench.train.fit` (and so ``wfbench train``) calls it after training, so
    ``ALGO:RUN/best.pt`` names a policy after every run; the file's ``best`` entry says it
    was not selected (``selected: False``, no score). The run's own ``best`` stays unset
    (nothing of training changes), so a resumed run with evaluation replaces the file at
    its first score. Returns the path written, or None when an evaluation had chosen ``best.pt``.
    """
    run = trainer.run
    if run.best["update"] is not None:
        return None
    ckpt = trainer.checkpoint()
    ckpt["best"] = {"score": None, "update": ckpt["update"], "global_step": run.global_step, "mode": None,
                    "selected": False, "why": "no evaluation on the public seeds ran: the last weights"}
    return save_atomic(ckpt, run.dir / "best.pt")


def save_atomic(ckpt: dict, path: Path) -> Path:
    """``torch.save`` through a temporary file, so a crash never leaves half a checkpoint at ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    torch.save(ckpt, tmp)
    tmp.replace(path)
    return path


def write_run_config(run: Run, model: torch.nn.Module, **extra) -> None:
    """``RUN/config.json``: every setting, the git commit, the parameter count, the device and the network's sizes."""
    run.dir.mkdir(parents=True, exist_ok=True)
    (run.dir / "config.json").write_text(json.dumps(
        {**asdict(run.config), **extra, "git_commit": run.commit, "parameters": count_parameters(model),
         "device": str(run.device), "model_config": run.network.to_dict()}, indent=2))


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10,
                             cwd=Path(__file__).resolve().parent)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, timeout=10, cwd=Path(__file__).resolve().parent).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "") if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


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


def torch_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def deployable(model: torch.nn.Module, variant: str, mode: str = "sample", name: str = "ppo"):
    """The policy the network makes: alone (joint) or with the heuristic workforce and positioning (dispatch)."""
    net = NetworkPolicy(copy.deepcopy(model).float().cpu(), mode=mode, device="cpu", name=name)
    if variant == "joint":
        return net
    return policies.Composite(net, "threshold", "spatial", name=name)
