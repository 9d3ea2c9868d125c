"""IMPALA for the paper's joint model: an actor with lagging parameters, a learner with V-trace (one file).

Espeholt et al. 2018, "IMPALA: Scalable Distributed Deep-RL with Importance Weighted
Actor-Learner Architectures". The network, the observation -> tensor step, the action
distributions, the reward shaping, the checkpoints and the public-seed selection are
those of the PPO trainer (:mod:`wfbench.train.ppo`, ``docs/rl.md``); what differs is who
acts with which parameters, and how the learner corrects for it::

    actor:   its own copy of the network, refreshed from the learner every K updates
             T steps of the B environments of a Simulator (staggered episodes, partial reset)
             -> a rollout: T + 1 observations, the actions, the behaviour log-probabilities mu,
                the shaped rewards, the episode ends, the LSTM state at the start, the
                version (the learner update whose parameters acted)
    learner: one gradient step per rollout
             rerun the network on the T + 1 steps from the stored LSTM state -> log pi, V
             V-trace (below) with rho = pi / mu -> value targets v_s and advantages
             loss = -rho_t A_t log pi  +  vf_coef * (v_s - V)^2 / 2  -  ent_coef * entropy
             Adam or RMSProp, global gradient clipping; every K updates publish the parameters

Two modes (``mode``):

- ``async``: the actor is a thread that puts rollouts into a bounded queue
  (``queue_size``) while the learner updates; the actor picks up the newest published
  parameters before each rollout. The policy lag (learner update - the version that
  acted) comes from the queue and from K; it depends on the timing of the two threads, so
  this mode is **not** deterministic.
- ``sync``: the same actor and learner called in turn in one thread; the lag is exactly
  ``update mod K`` (0, 1, ..., K - 1, 0, ...). Deterministic on CPU given ``seed``.

With ``address`` set (``"local"``, ``"auto"``, ``"ray://host:port"``) the actors are
``ray_actors`` Ray actors instead of the thread (:class:`RemoteActor`, on this machine or
a cluster; the plumbing is in :mod:`wfbench.train.ray_actors`, imported only then, so Ray
stays optional). Each is an :class:`Actor` on CPU with its own Simulator on its own share
of the training seeds, making the same rollouts; the learner stays in this process. Like
``async``, such a run is **not** deterministic.

V-trace (section 4.1 of the paper), per environment, for t = T-1 down to 0, with
``rho_t = min(rho_bar, pi/mu)``, ``c_t = lambda * min(c_bar, pi/mu)`` and
``gamma_t = gamma * (1 - done_t)`` (no bootstrap across an episode's end)::

    delta_t = rho_t * (r_t + gamma_t V(x_{t+1}) - V(x_t))
    v_t     = V(x_t) + delta_t + gamma_t c_t (v_{t+1} - V(x_{t+1}))      (v_T = V(x_T), the bootstrap)
    A_t     = rho_t * (r_t + gamma_t v_{t+1} - V(x_t))

On-policy (pi = mu) with rho_bar, c_bar >= 1 and lambda = 1, v_t is the n-step return
bootstrapped from V(x_T), i.e. GAE(lambda = 1)'s return (``tests/test_impala.py`` checks it).

Checkpoints are PPO checkpoints (the same keys, plus ``algo: impala``), so
``ppo:RUN/best.pt`` loads one as a policy. ``best.pt`` is chosen on the **public** seeds
(``eval_seeds``, a part of 1000-1049), never on the test seeds.
"""

from __future__ import annotations

import copy
import math
import queue
import re
import threading
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from policies.neural.dist import env_action, gumbel, log_prob_entropy, noise_shapes, sample
from policies.neural.model import OBS_KEYS, WorkforceNet, featurize, model_config, obs_to_torch
from policies.neural.policy import load_checkpoint
from wfbench.backends import require_ray
from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import SEED_SETS, resolve_seeds
from wfbench.core.simulator import Simulator
from wfbench.train.common import (
    RunningStd,
    RunOutputs,
    deployable,
    git_commit,
    policy_checkpoint,
    save_atomic,
    score_public,
    torch_device,
    write_run_config,
)
from wfbench.train.ppo import VARIANTS

MODES = ("async", "sync")
OPTIMIZERS = ("adam", "rmsprop")
# address: "" (no Ray), "local" (a Ray instance started on this machine), "auto" (the cluster this machine is in)
# or a cluster's address, "ray://HOST:PORT" (Ray client) or "HOST:PORT" (its head node)
RAY_ADDRESS = re.compile(r"local|auto|(ray://)?[^\s/]+:\d+")


@dataclass
class ImpalaConfig:
    """Every setting of an IMPALA run; saved as ``config.json`` and in each checkpoint."""

    scenario: str = "paper-64"
    variant: str = "joint"  # joint only (the paper trains joint IMPALA)
    model: str = "cpu"  # policies.neural.model.PRESETS
    steps: int = 1_000_000  # environment steps in all (B per simulator step)
    num_envs: int = 32  # B: environments of the actor's simulator
    num_steps: int = 32  # T: steps per rollout (the unroll length)
    mode: str = "async"  # async: actor thread + bounded queue; sync: actor and learner in turn
    queue_size: int = 1  # async: rollouts waiting for the learner, at most
    sync_every: int = 1  # K: the actor's parameters are refreshed from the learner every K updates
    optimizer: str = "adam"  # adam | rmsprop
    lr: float = 3e-4
    rms_alpha: float = 0.99  # rmsprop's smoothing constant
    eps: float = 1e-5  # the optimizer's epsilon (the losses are means over T x B, so a small one)
    gamma: float = 0.995
    rho_bar: float = 1.0  # truncation of the importance weight in delta_t and the policy gradient
    c_bar: float = 1.0  # truncation of the trace coefficient c_t
    vtrace_lambda: float = 1.0  # c_t = lambda * min(c_bar, pi / mu)
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    reward_offset: float = 0.7  # reward = (NSW_t - offset) * scale, as ppo.py's joint variant
    reward_scale: float = 10.0
    normalize_returns: bool = True
    stagger: bool = True  # staggered episodes by partial reset
    seed: int = 0
    device: str = "auto"  # auto | cpu | cuda
    bf16: bool = True  # CUDA only: autocast of the forward passes
    threads: int = 1  # torch CPU threads (per thread of this process; the simulator uses numba's)
    checkpoint_every: int = 20  # updates
    eval_every: int = 20  # updates; 0: never
    eval_seeds: str = "public:10"  # a part of the public set: checkpoint selection only
    run_dir: str = "runs/impala"
    init: str = ""  # a checkpoint whose network weights start this run (fine-tuning); nothing else is taken
    model_overrides: dict = field(default_factory=dict)
    address: str = ""  # "": the actor thread of `mode`; else Ray actors: "local", "auto", "ray://HOST:PORT"
    ray_actors: int = 2  # with address: Ray actors, each with num_envs environments (one CPU x threads each)

    def validate(self) -> None:
        if self.variant != "joint":
            raise ValueError(f"variant {self.variant!r} is not allowed for impala; allowed: joint")
        if self.mode not in MODES:
            raise ValueError(f"mode {self.mode!r} is not allowed; allowed: {', '.join(MODES)}")
        if self.optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer {self.optimizer!r} is not allowed; allowed: {', '.join(OPTIMIZERS)}")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"device {self.device!r} is not allowed; allowed: auto, cpu, cuda")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device 'cuda' asked for, but torch sees no CUDA device (use --device cpu or auto)")
        for name in ("steps", "num_envs", "num_steps", "queue_size", "sync_every", "threads", "checkpoint_every",
                     "ray_actors"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} = {v!r} is not allowed; allowed: an integer >= 1")
        if not isinstance(self.eval_every, int) or self.eval_every < 0:
            raise ValueError(f"eval_every = {self.eval_every!r} is not allowed; allowed: an integer >= 0")
        for name in ("gamma", "vtrace_lambda", "rms_alpha"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"{name} = {getattr(self, name)} is not allowed; allowed: a number in (0, 1]")
        for name in ("rho_bar", "c_bar", "lr", "eps", "max_grad_norm"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} = {getattr(self, name)} is not allowed; allowed: a number > 0")
        if self.c_bar > self.rho_bar:
            raise ValueError(f"c_bar = {self.c_bar} > rho_bar = {self.rho_bar} is not allowed; allowed: "
                             "c_bar <= rho_bar (the paper's assumption)")
        for name in ("ent_coef", "vf_coef", "reward_scale"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} = {getattr(self, name)} is not allowed; allowed: a number >= 0")
        ScenarioConfig.resolve(self.scenario)
        seeds = resolve_seeds(self.eval_seeds)
        if not set(seeds) <= set(SEED_SETS["public"]):
            raise ValueError(f"eval_seeds {self.eval_seeds!r}: checkpoints are selected on the public seeds "
                             "(1000-1049) only, never on test seeds")
        model_config(self.model, VARIANTS[self.variant], **self.model_overrides)
        if not isinstance(self.address, str) or (self.address and not RAY_ADDRESS.fullmatch(self.address)):
            raise ValueError(f"address {self.address!r} is not allowed; allowed: '' (no Ray), 'local', 'auto', "
                             "'ray://HOST:PORT' or 'HOST:PORT'")
        if self.address:
            if self.mode != "async":
                raise ValueError(f"mode {self.mode!r} is not allowed with address (Ray actors run beside the "
                                 "learner); allowed: async")
            require_ray(f"address {self.address!r}")

    @classmethod
    def from_dict(cls, d: dict) -> ImpalaConfig:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


# -- V-trace ------------------------------------------------------------------------------------
class VTrace(NamedTuple):
    vs: torch.Tensor  # (T, B) value targets
    pg_adv: torch.Tensor  # (T, B) rho_t * (r_t + gamma_t v_{t+1} - V(x_t))
    rhos: torch.Tensor  # (T, B) the truncated importance weights


@torch.no_grad()
def vtrace(log_rhos: torch.Tensor, rewards: torch.Tensor, discounts: torch.Tensor, values: torch.Tensor,
           bootstrap: torch.Tensor, rho_bar: float = 1.0, c_bar: float = 1.0, lam: float = 1.0) -> VTrace:
    """V-trace targets and advantages (all (T, B), time major; ``bootstrap`` (B,) is V(x_T)).

    ``log_rhos`` = log pi(a_t|x_t) - log mu(a_t|x_t) (target minus behaviour);
    ``discounts`` = gamma * (1 - done_t).
    """
    rhos = log_rhos.exp()
    clipped = rhos.clamp(max=rho_bar)
    cs = lam * rhos.clamp(max=c_bar)
    next_values = torch.cat([values[1:], bootstrap[None]])
    deltas = clipped * (rewards + discounts * next_values - values)
    diff = torch.zeros_like(bootstrap)  # v_{t+1} - V(x_{t+1}), zero after the last step
    vs_minus_v = torch.empty_like(values)
    for t in reversed(range(values.shape[0])):
        diff = deltas[t] + discounts[t] * cs[t] * diff
        vs_minus_v[t] = diff
    vs = values + vs_minus_v
    next_vs = torch.cat([vs[1:], bootstrap[None]])
    pg_adv = clipped * (rewards + discounts * next_vs - values)
    return VTrace(vs, pg_adv, clipped)


# -- the actor ----------------------------------------------------------------------------------
class Actor:
    """Steps the batched simulator with its own (lagging) copy of the network; makes rollouts.

    ``index`` of ``count``: the thread path has one actor (0 of 1); the Ray path ``ray_actors``,
    each on its own share of the training seeds and with its own random generator.
    """

    def __init__(self, cfg: ImpalaConfig, scenario: ScenarioConfig, model: WorkforceNet, device: torch.device,
                 index: int = 0, count: int = 1):
        self.cfg, self.scenario, self.device = cfg, scenario, device
        self.index, self.count = index, count
        self.model = copy.deepcopy(model).eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.version = -1  # the learner update whose parameters this copy holds
        self.gen = torch.Generator(device=device).manual_seed(cfg.seed + 1_000_003 * index)
        self.ret_std = RunningStd()
        self.seed_cursor, self.episode, self.steps = 0, 0, 0
        self.timing = {"simulator": 0.0, "forward": 0.0}
        self.sim = None

    def load(self, version: int, params: dict) -> None:
        self.model.load_state_dict(params)
        self.version = version

    def meta(self) -> dict:
        """What a checkpoint needs of the actor to resume (taken as each rollout is finished)."""
        return {"seed_cursor": self.seed_cursor, "episode": self.episode, "ret_std": dict(vars(self.ret_std)),
                "generator": self.gen.get_state()}

    def restore(self, meta: dict) -> None:
        self.seed_cursor, self.episode = meta["seed_cursor"], meta["episode"]
        self.ret_std.__dict__.update(meta["ret_std"])
        self.gen.set_state(meta["generator"].cpu())  # a generator state is a CPU ByteTensor, on any device

    def _take_seeds(self, k: int) -> list[int]:
        """The next ``k`` seeds of the ``train`` set for this run (as ppo.py: a window per run seed).

        Actor ``index`` of ``count`` takes every ``count``-th seed of the window from ``index`` on,
        so the actors' seeds are disjoint and together are the window one actor would take.
        """
        train, n = SEED_SETS["train"], self.count
        start = (self.cfg.seed * 1_000_003 + self.seed_cursor * n + self.index) % (len(train) - k * n)
        self.seed_cursor += k
        return list(train[start:start + k * n:n])

    def start(self) -> None:
        """A fresh Simulator; with ``stagger`` environment b's first episode is cut after (b + 1) / B of the horizon."""
        self.sim = Simulator(self.scenario, self._take_seeds(self.cfg.num_envs), keep_series=False, threads=1)
        self.obs = self.sim.reset()
        H, B = self.scenario.horizon, self.sim.B
        self.cut = (H * (np.arange(B) + 1)) // B if self.cfg.stagger else np.full(B, H)
        self.state = self.model.initial_state(B, self.device)
        self.starts = torch.ones(B, device=self.device)
        self.ret = np.zeros(B)

    def _autocast(self):
        cuda = self.device.type == "cuda"
        return torch.autocast(device_type=self.device.type, dtype=torch.bfloat16, enabled=cuda and self.cfg.bf16)

    @torch.no_grad()
    def rollout(self) -> dict:
        c, dev, T = self.cfg, self.device, self.cfg.num_steps
        if self.sim is None:
            self.start()
        B, M, N = self.sim.B, self.sim.M, self.sim.N
        buf: dict = {k: [] for k in ("raw", "starts", "dispatch", "workforce", "positioning", "logp", "reward",
                                     "done")}
        init_state = tuple(s.clone() for s in self.state)
        episodes = []
        for _ in range(T):
            t0 = time.perf_counter()
            raw = obs_to_torch(self.obs, dev)
            x = featurize(raw, self.model.config.coord_scale)
            with self._autocast():
                out, self.state = self.model(x, self.state, self.starts[None])
            noise = {k: gumbel(s, self.gen, dev) for k, s in noise_shapes(B, M, N).items()}
            acts = sample(out, x, noise)
            logp, _, _ = log_prob_entropy(out, x, acts)
            action = env_action(acts, M)
            t1 = time.perf_counter()
            buf["raw"].append(raw)
            buf["starts"].append(self.starts)
            for k in ("dispatch", "workforce", "positioning"):
                buf[k].append(acts[k])
            buf["logp"].append(logp.float())
            nsw, self.obs = self.sim.step_observe(action)
            reward = (nsw - c.reward_offset) * c.reward_scale  # ppo.py's joint reward
            ended = self.sim.dones | (self.sim.state.t >= self.cut)
            self.steps += B
            if c.normalize_returns:
                self.ret = self.ret * c.gamma + reward
                self.ret_std.update(self.ret)
                reward = reward / self.ret_std.std
                self.ret[ended] = 0.0
            buf["reward"].append(torch.as_tensor(reward, dtype=torch.float32, device=dev))
            buf["done"].append(torch.as_tensor(ended, dtype=torch.float32, device=dev))
            if ended.any():
                full = self.sim.dones  # whole episodes only in the logs (not the cut first ones)
                if full.any():
                    means = self.sim.episode_means()
                    episodes.append({k: float(np.mean(means[k][full])) for k in ("nsw", "workforce_cost",
                                                                                 "utilization", "downtime")})
                self.episode += int(ended.sum())
                idx = np.flatnonzero(ended)  # partial reset onto fresh training seeds
                self.obs = self.sim.reset(indices=idx, seeds=self._take_seeds(len(idx)))
                self.cut[idx] = self.scenario.horizon
            self.starts = torch.as_tensor(ended, dtype=torch.float32, device=dev)
            self.timing["forward"] += t1 - t0
            self.timing["simulator"] += time.perf_counter() - t1
        # the (T + 1)-th observation: the learner's bootstrap V(x_T) (the next rollout starts from it)
        buf["raw"].append(obs_to_torch(self.obs, dev))
        buf["starts"].append(self.starts)
        roll = {k: torch.stack(v) for k, v in buf.items() if k != "raw"}
        roll["raw"] = {k: torch.stack([r[k] for r in buf["raw"]]) for k in OBS_KEYS}  # (T + 1, B, ...)
        roll["init_state"] = init_state
        roll["episodes"] = episodes
        roll["version"] = self.version
        roll["actor"] = self.index
        roll["meta"] = self.meta()
        return roll


class RemoteActor:
    """The Ray path's actor: an :class:`Actor` on CPU, ``index`` of ``cfg.ray_actors``, in a Ray worker process.

    A plain class: :mod:`wfbench.train.ray_actors` makes it a Ray actor (``ray.remote``), so this
    module needs no Ray. Ray pickles ``cfg`` and ``meta`` to the worker, which builds its own
    network and Simulator; ``params`` arrive as a CPU state_dict from the learner's ``ray.put``.
    """

    def __init__(self, cfg: ImpalaConfig, index: int, meta: dict | None):
        torch.set_num_threads(cfg.threads)
        model = WorkforceNet(model_config(cfg.model, VARIANTS[cfg.variant], **cfg.model_overrides))
        self.actor = Actor(cfg, ScenarioConfig.resolve(cfg.scenario), model, torch.device("cpu"), index,
                           cfg.ray_actors)
        if meta is not None:  # resume: this actor's return normalizer, generator and seed cursor
            self.actor.restore(meta)
        self.actor.start()  # its Simulator, on its first training seeds

    def ready(self) -> int:
        """Answers once the actor is built (the learner waits for all before it starts the clock)."""
        return self.actor.index

    def rollout(self, version: int, params: dict) -> dict:
        """One rollout, acting with the learner's parameters of update ``version`` (loaded when they are new)."""
        if version != self.actor.version:
            self.actor.load(version, params)
        return self.actor.rollout()


def _to_device(roll: dict, device: torch.device) -> dict:
    """A rollout made on CPU (by a Ray actor) on the learner's device."""
    if device.type == "cpu":
        return roll
    out = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in roll.items()}
    out["raw"] = {k: v.to(device) for k, v in roll["raw"].items()}
    out["init_state"] = tuple(s.to(device) for s in roll["init_state"])
    return out


# -- the learner --------------------------------------------------------------------------------
class Trainer:
    """An IMPALA run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint."""

    def __init__(self, config: ImpalaConfig, resume: str | Path | None = None, progress: bool = True,
                 log: bool = True):
        config.validate()
        self.cfg = c = config
        self.device = torch_device(c.device)
        self.cuda = self.device.type == "cuda"
        torch.set_num_threads(c.threads)
        torch.manual_seed(c.seed)
        self.scenario = ScenarioConfig.resolve(c.scenario)
        self.mcfg = model_config(c.model, VARIANTS[c.variant], **c.model_overrides)
        self.model = WorkforceNet(self.mcfg).to(self.device)
        if c.optimizer == "adam":
            self.opt = torch.optim.Adam(self.model.parameters(), lr=c.lr, eps=c.eps)
        else:
            self.opt = torch.optim.RMSprop(self.model.parameters(), lr=c.lr, alpha=c.rms_alpha, eps=c.eps)
        self.update, self.global_step = 0, 0
        self.best = {"score": -math.inf, "update": None}
        self.history: list[dict] = []
        self.lags: list[int] = []  # the policy lag of every update, in order
        self.progress, self.log = progress, log
        self.run_dir = Path(c.run_dir)
        self.commit = git_commit()
        self.timing = {"update": 0.0, "wait": 0.0}
        if c.init and resume is None:
            start = load_checkpoint(c.init, str(self.device))
            if start["model_config"] != self.mcfg.to_dict():
                raise ValueError(f"--init {c.init!r}: its network ({start['model_config']}) is not this run's "
                                 f"--model {c.model}")
            self.model.load_state_dict(start["model"])
        # the thread path's actor, here; the Ray path's live in Ray workers (started by train())
        self.actor = None if c.address else Actor(c, self.scenario, self.model, self.device)
        self.n_actors = c.ray_actors if c.address else 1
        # what a checkpoint needs of each actor, as of its last rollout the learner used (None: none yet)
        self.actor_metas: list[dict | None] = [self.actor.meta()] if self.actor else [None] * self.n_actors
        if resume is not None:
            self._load(resume)
        self._lock = threading.Lock()
        self._published: tuple[int, dict] = (-1, {})
        self._ray = None  # wfbench.train.ray_actors.RayActors while train() runs, with address set
        self.publish()

    # -- parameters from the learner to the actor ---------------------------------------------
    def publish(self) -> None:
        """Make the learner's current parameters the ones the actors pick up next (version = update)."""
        params = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        with self._lock:
            self._published = (self.update, params)
        if self._ray is not None:
            self._ray.publish(self.update, params)

    def _refresh_actor(self) -> None:
        with self._lock:
            version, params = self._published
        if version != self.actor.version:
            self.actor.load(version, params)

    def _autocast(self):
        return torch.autocast(device_type=self.device.type, dtype=torch.bfloat16, enabled=self.cuda and self.cfg.bf16)

    # -- one learner step -----------------------------------------------------------------------
    def learn(self, roll: dict) -> dict:
        c = self.cfg
        t0 = time.perf_counter()
        T, B = roll["logp"].shape
        raw = {k: v.flatten(0, 1) for k, v in roll["raw"].items()}  # (T + 1) * B rows, time major
        x = featurize(raw, self.mcfg.coord_scale)
        with self._autocast():
            out, _ = self.model(x, roll["init_state"], roll["starts"])
        values = out["value"].float().view(T + 1, B)
        n = T * B  # the last step's rows only give the bootstrap value
        heads = {k: v[:n] for k, v in out.items() if k != "value"}
        acts = {k: roll[k].flatten(0, 1) for k in ("dispatch", "workforce", "positioning")}
        logp, ent, parts = log_prob_entropy(heads, {k: v[:n] for k, v in x.items()}, acts)
        logp = logp.view(T, B)
        log_rhos = logp.detach() - roll["logp"]
        vt = vtrace(log_rhos, roll["reward"], c.gamma * (1.0 - roll["done"]), values[:T].detach(),
                    values[T].detach(), c.rho_bar, c.c_bar, c.vtrace_lambda)
        pg_loss = -(vt.pg_adv * logp).mean()
        v_loss = 0.5 * ((vt.vs - values[:T]) ** 2).mean()
        entropy = ent.mean()
        loss = pg_loss + c.vf_coef * v_loss - c.ent_coef * entropy
        self.opt.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(self.model.parameters(), c.max_grad_norm)
        self.opt.step()
        lag = self.update - roll["version"]
        self.lags.append(lag)
        self.timing["update"] += time.perf_counter() - t0
        rhos = log_rhos.exp()
        stats = {"pg_loss": pg_loss.item(), "v_loss": v_loss.item(), "entropy": entropy.item(),
                 "grad_norm": float(grad_norm), "policy_lag": float(lag),
                 "rho_mean": float(rhos.mean()), "rho_clipfrac": float((rhos > c.rho_bar).float().mean()),
                 "abs_log_rho": float(log_rhos.abs().mean()), "approx_kl": float(((rhos - 1) - log_rhos).mean()),
                 "vs_mean": float(vt.vs.mean())}
        for k, v in parts.items():
            stats[f"ent_{k}"] = float(v.detach().mean())
        return stats

    # -- evaluation and checkpoints -------------------------------------------------------------
    def policy(self, mode: str = "sample"):
        return deployable(self.model, self.cfg.variant, mode, name=f"impala-{self.cfg.variant}")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        return score_public(self.policy, self.scenario, self.cfg.eval_seeds)

    def checkpoint(self) -> dict:
        """The shared checkpoint keys (so ``ppo:PATH`` loads it), plus ``algo``."""
        metas = [m for m in self.actor_metas if m is not None]
        return policy_checkpoint(self.model, self.mcfg, self.cfg.variant, self.scenario.name, self.cfg,
                                 algo="impala", update=self.update, global_step=self.global_step,
                                 episode=sum(m["episode"] for m in metas),
                                 seed_cursor=sum(m["seed_cursor"] for m in metas),  # training seeds taken, all actors
                                 git_commit=self.commit, best=self.best, history=self.history)

    def save(self, path: Path, full: bool = True) -> Path:
        ckpt = self.checkpoint()
        if full:  # what --resume needs on top of the policy
            ckpt["optimizer"] = self.opt.state_dict()
            ckpt["actors"] = list(self.actor_metas)  # each actor's return normalizer, generator and seed cursor
            ckpt["torch_rng"] = torch.get_rng_state()
            ckpt["lags"] = list(self.lags)
        return save_atomic(ckpt, path)

    def _load(self, path) -> None:
        ckpt = load_checkpoint(path, str(self.device))
        if "optimizer" not in ckpt:
            raise ValueError(f"checkpoint {str(path)!r} has no optimizer state: it cannot be resumed")
        if ckpt.get("algo") != "impala":
            raise ValueError(f"checkpoint {str(path)!r} is not an impala run (algo {ckpt.get('algo', 'ppo')!r})")
        if ckpt["model_config"] != self.mcfg.to_dict():
            raise ValueError(f"checkpoint {str(path)!r} is a run of another model; resume with the settings of "
                             "its config.json")
        self.model.load_state_dict(ckpt["model"])
        self.opt.load_state_dict(ckpt["optimizer"])
        torch.set_rng_state(ckpt["torch_rng"].cpu())
        self.update, self.global_step = ckpt["update"], ckpt["global_step"]
        self.commit = ckpt.get("git_commit", self.commit)
        self.best, self.history, self.lags = ckpt["best"], ckpt["history"], list(ckpt.get("lags", []))
        metas = ckpt.get("actors") or [{k: ckpt[k] for k in ("seed_cursor", "episode", "ret_std", "generator")}]
        if len(metas) != self.n_actors:  # each actor's seeds are every n-th of the window: n cannot change
            raise ValueError(f"checkpoint {str(path)!r} was made by {len(metas)} actor(s), this run has "
                             f"{self.n_actors}; resume with its address and ray_actors (config.json)")
        self.actor_metas = metas
        if self.actor is not None:
            self.actor.restore(metas[0])  # a fresh batch of episodes on the next training seeds

    # -- where rollouts come from -------------------------------------------------------------
    def _actor_thread(self, count: int) -> None:
        """Async mode: make ``count`` rollouts into the queue, each with the newest published parameters."""
        try:
            for _ in range(count):
                if self._stop.is_set():
                    return
                self._refresh_actor()
                roll = self.actor.rollout()
                while not self._stop.is_set():
                    try:
                        self._queue.put(roll, timeout=0.1)
                        break
                    except queue.Full:
                        continue
        except BaseException as exc:  # noqa: BLE001  (handed to the learner, which raises it)
            self._actor_error = exc

    def _next_rollout(self) -> dict:
        t0 = time.perf_counter()
        if self._ray is not None:
            roll = self._ray.next()
            self.timing["wait"] += time.perf_counter() - t0
            return _to_device(roll, self.device)
        if self.cfg.mode == "sync":
            self._refresh_actor()
            roll = self.actor.rollout()
        else:
            while True:
                try:
                    roll = self._queue.get(timeout=0.1)
                    break
                except queue.Empty:
                    if self._actor_error is not None:
                        raise RuntimeError(f"the actor thread failed: {self._actor_error!r}") from self._actor_error
                    if not self._thread.is_alive():
                        raise RuntimeError("the actor thread stopped without a rollout") from None
            self.timing["wait"] += time.perf_counter() - t0
        return roll

    def _start_actor(self, count: int) -> None:
        self._queue: queue.Queue = queue.Queue(maxsize=self.cfg.queue_size)
        self._stop = threading.Event()
        self._actor_error: BaseException | None = None
        self._thread = threading.Thread(target=self._actor_thread, args=(count,), name="impala-actor", daemon=True)
        self._thread.start()

    def _stop_actor(self) -> None:
        self._stop.set()
        while self._thread.is_alive():
            try:  # unblock a put
                self._queue.get(timeout=0.05)
            except queue.Empty:
                pass
        self._thread.join()

    def _start_ray(self, count: int) -> None:
        """Ray path: start (or join) Ray and the ``ray_actors`` actors, and ask for ``count`` rollouts."""
        from wfbench.train.ray_actors import RayActors  # Ray is imported on this path only

        with self._lock:
            version, params = self._published
        self._ray = RayActors(self.cfg, RemoteActor, self.actor_metas, version, params)
        self._ray.run(count)

    def _stop_actors(self) -> None:
        """Stop the actor thread, or kill the Ray actors and shut Ray down if this run started it."""
        if self.cfg.mode == "async" and hasattr(self, "_thread"):
            self._stop_actor()
            del self._thread
        if self._ray is not None:
            self._ray.close()
            self._ray = None

    # -- the loop -----------------------------------------------------------------------------
    def train(self, updates: int | None = None) -> dict:
        """Train until ``cfg.steps`` environment steps (or ``updates`` more updates); returns the last stats."""
        c = self.cfg
        per_update = c.num_envs * c.num_steps
        total_updates = math.ceil(c.steps / per_update)
        stop = total_updates if updates is None else min(total_updates, self.update + updates)
        write_run_config(self.run_dir, c, self.model, self.mcfg, self.device, self.commit, algo="impala")
        how = f"ray x{c.ray_actors}" if c.address else c.mode
        stats: dict = {}
        start, start_step = time.perf_counter(), self.global_step
        with RunOutputs(self, "update", f"impala {how} {self.scenario.name}", stop * per_update,
                        self.update * per_update, cleanup=self._stop_actors) as out:
            if c.mode == "async" and not c.address and stop > self.update:
                self._start_actor(stop - self.update)
            if c.address and stop > self.update:
                self._start_ray(stop - self.update)
                start = time.perf_counter()  # env-steps/s once the actors are built (not Ray's start-up)
            while self.update < stop:
                roll = self._next_rollout()
                stats = self.learn(roll)
                self.update += 1
                self.global_step += per_update
                self.actor_metas[roll["actor"]] = roll["meta"]
                if self.update % c.sync_every == 0:
                    self.publish()
                sps = (self.global_step - start_step) / (time.perf_counter() - start)
                out.episodes(roll["episodes"])
                out.scalars("loss", stats)
                out.scalars("charts", {"env_steps_per_s": sps, "reward_std": roll["meta"]["ret_std"]["var"] ** 0.5,
                                       "learner_wait_s": self.timing["wait"]})
                if c.eval_every and self.update % c.eval_every == 0:
                    res = self.evaluate_public()
                    self.history.append({"update": self.update, "global_step": self.global_step, **res})
                    out.public(res, self.update)
                if self.update % c.checkpoint_every == 0:
                    out.checkpoint(f"update_{self.update:06d}.pt")
                out.advance(per_update, {"sps": f"{sps:.0f}", "lag": f"{np.mean(self.lags[-20:]):.1f}"})
        return stats
