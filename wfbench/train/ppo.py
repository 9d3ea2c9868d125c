"""PPO for the paper's joint model, driving the batched simulator directly (one readable file).

The loop, per update::

    rollout: T steps of the B environments of a Simulator
             observation -> tensors (policies.neural.model.featurize, no loop over environments)
             network forward (no grad) -> sample actions (policies.neural.dist) -> sim.step_observe
    returns: GAE(gamma, lambda) on the shaped rewards, the value of the last observation bootstrapped
    update:  epochs x minibatches of whole sequences (a minibatch is a set of environments with all
             T of their steps, so the LSTM is rerun from the state it had at the rollout's start);
             clipped policy objective, clipped value loss, entropy bonus, global gradient clipping

Episodes (``stagger``, the default for ``joint``) are staggered by partial reset: the
first episode of environment b is cut after (b + 1) / B of the horizon, and from then on
every environment that reaches the horizon is reset alone onto the next seed of the
``train`` set (``wfbench.core.seeds``) with ``Simulator.reset(indices, seeds)``, so a rollout
mixes every phase of the episode. The ``dispatch`` variant (whose heuristic parts keep
per-environment memory that resets with the batch) and ``stagger=False`` run synchronized
episodes: the B environments end together and a new Simulator is made on the next B
training seeds. Either way the LSTM state is reset where an episode starts (the
``starts`` flags) and the returns do not bootstrap across an episode's end. Only whole
episodes are logged (``episode/*``), not the cut first ones.

Rewards (documented in docs/rl.md):

- ``joint``: ``(NSW_t - offset) * scale`` with offset 0.7 and scale 10 (the per-step NSW
  of the scenario, workforce cost included), divided by a running standard deviation of
  the discounted return (the usual return normalization).
- ``dispatch``: the same with NSW_t without its workforce-cost term, the geometric mean
  of the utilization and downtime utilities, ``sqrt(u_PUR * u_AFD)`` (the paper's
  dispatch-only model); the network has only the dispatch head, the heuristic
  workforce (``threshold``) and positioning (``spatial``) rules make the other decisions.

Agents (``agents``): ``joint`` (the default) is the paper's joint model, one network and
one critic for the three decisions. ``independent`` is the multi-agent reading of the
PettingZoo environment (``wfbench.envs.parallel``): one network per decision
(:class:`policies.neural.model.AgentSet`), no shared parameter, each seeing the whole
observation and each with its own critic; the agents share the environment's reward (the
step's NSW, as every PettingZoo agent gets it), and each has its own GAE advantage and
clipped ratio on its own head's log-probability (independent PPO). Their losses are
summed and their gradients clipped per agent, which is the same as three PPO updates side
by side. A trained set is saved and loaded like a joint network (``ppo:RUN/best.pt``).

Value warm-up (``value_warmup``): the first updates fit the value heads alone, the policy
frozen; for fine-tuning (``init``) a network whose value head never learned (a
hindsight-learned one, :mod:`wfbench.train.hindsight`).

Checkpoints: ``RUN/checkpoints/update_<n>.pt`` every ``checkpoint_every`` updates,
``RUN/latest.pt`` (also on Ctrl-C) and ``RUN/best.pt``: the checkpoint with the highest
mean NSW on the **public** seeds (``eval_seeds``, a part of 1000-1049; never the test
seeds), scored through ``wfbench.evaluate`` in the checkpoint's default (sampled) mode.
Each checkpoint records the seeds it was selected on.

Same code on CPU and CUDA; on CUDA the forward passes run under bf16 autocast (the
heads and the value in fp32) and ``compile=True`` wraps the network in ``torch.compile``.
On CPU a run is deterministic given ``seed``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import torch

import policies
from policies.neural.dist import env_action, gumbel, head_log_prob_entropy, noise_shapes, sample
from policies.neural.model import (
    OBS_KEYS,
    AgentSet,
    WorkforceNet,
    agent_set_config,
    featurize,
    model_config,
    obs_to_torch,
)
from policies.neural.policy import load_checkpoint
from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import SEED_SETS, resolve_seeds
from wfbench.core.simulator import Simulator
from wfbench.core.state import METRICS
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

AGENTS = ("joint", "independent")
VARIANTS = {
    "joint": ("dispatch", "workforce", "positioning"),
    "dispatch": ("dispatch",),
}
_K_NSW, _K_UPUR, _K_UAFD = METRICS.index("nsw"), METRICS.index("u_utilization"), METRICS.index("u_downtime")


@dataclass
class TrainConfig:
    """Every setting of a run; saved as ``config.json`` in the run directory and in each checkpoint."""

    scenario: str = "paper-64"
    variant: str = "joint"
    agents: str = "joint"  # AGENTS: one network for all decisions, or one per decision (independent)
    model: str = "small"  # policies.neural.model.PRESETS
    steps: int = 1_000_000  # environment steps in all (B per simulator step)
    num_envs: int = 32  # B
    num_steps: int = 32  # T: steps per rollout
    epochs: int = 2
    minibatches: int = 2
    lr: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    clip: float = 0.2
    vf_clip: float = 0.2
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    reward_offset: float = 0.7
    reward_scale: float = 10.0
    normalize_returns: bool = True
    stagger: bool = True  # joint: staggered episodes by partial reset (dispatch: always synchronized)
    seed: int = 0
    device: str = "auto"  # auto | cpu | cuda
    bf16: bool = True  # CUDA only
    compile: bool = False  # CUDA only: torch.compile of the network
    threads: int = 1  # torch CPU threads (the simulator uses numba's)
    checkpoint_every: int = 20  # updates
    eval_every: int = 20  # updates; 0: never
    eval_seeds: str = "public:10"  # a part of the public set: checkpoint selection only
    run_dir: str = "runs/ppo"
    init: str = ""  # a checkpoint whose network weights start this run (fine-tuning); nothing else is taken
    value_warmup: int = 0  # first updates that fit the value head alone, the policy frozen (fine-tuning --init)
    model_overrides: dict = field(default_factory=dict)

    def validate(self) -> None:
        if self.variant not in VARIANTS:
            raise ValueError(f"variant {self.variant!r} is not allowed; allowed: {', '.join(VARIANTS)}")
        if self.agents not in AGENTS:
            raise ValueError(f"agents {self.agents!r} is not allowed; allowed: {', '.join(AGENTS)}")
        if self.agents == "independent" and self.variant != "joint":
            raise ValueError(f"agents 'independent' needs variant 'joint' (variant {self.variant!r} has one "
                             "decision, so one agent)")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"device {self.device!r} is not allowed; allowed: auto, cpu, cuda")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device 'cuda' asked for, but torch sees no CUDA device (use --device cpu or auto)")
        for name in ("steps", "num_envs", "num_steps", "epochs", "minibatches", "threads", "checkpoint_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} = {getattr(self, name)} is not allowed; allowed: an integer >= 1")
        if self.value_warmup < 0:
            raise ValueError(f"value_warmup = {self.value_warmup} is not allowed; allowed: an integer >= 0")
        for name in ("gamma", "gae_lambda"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"{name} = {getattr(self, name)} is not allowed; allowed: a number in (0, 1]")
        if self.num_envs % self.minibatches:
            raise ValueError(f"num_envs = {self.num_envs} must be a multiple of minibatches = {self.minibatches}")
        ScenarioConfig.resolve(self.scenario)
        seeds = resolve_seeds(self.eval_seeds)
        public = set(SEED_SETS["public"])
        if not set(seeds) <= public:
            raise ValueError(f"eval_seeds {self.eval_seeds!r}: checkpoints are selected on the public seeds "
                             "(1000-1049) only, never on test seeds")
        self.network_config()

    def network_config(self):
        """The network's config: one ModelConfig (joint) or one per decision (independent agents)."""
        if self.agents == "independent":
            return agent_set_config(self.model, VARIANTS[self.variant], **self.model_overrides)
        return model_config(self.model, VARIANTS[self.variant], **self.model_overrides)

    @classmethod
    def from_dict(cls, d: dict) -> TrainConfig:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


class Trainer:
    """A PPO run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint."""

    def __init__(self, config: TrainConfig, resume: str | Path | None = None, progress: bool = True,
                 log: bool = True):
        config.validate()
        self.cfg = c = config
        self.device = torch_device(c.device)
        self.cuda = self.device.type == "cuda"
        torch.set_num_threads(c.threads)
        torch.manual_seed(c.seed)
        self.scenario = ScenarioConfig.resolve(c.scenario)
        self.decisions = VARIANTS[c.variant]
        self.mcfg = c.network_config()
        independent = c.agents == "independent"
        self.model = (AgentSet(self.mcfg) if independent else WorkforceNet(self.mcfg)).to(self.device)
        # the agents: their heads, and the parameters each one's gradient is clipped over
        if independent:
            self.agents = {d: (d,) for d in self.decisions}
            self.clip_groups = [list(m.parameters()) for m in self.model.members.values()]
        else:
            self.agents = {"joint": self.decisions}
            self.clip_groups = [list(self.model.parameters())]
        self.opt = torch.optim.Adam(self.model.parameters(), lr=c.lr, eps=1e-5)
        # value warm-up (fine-tuning a network whose value head never learned, e.g. a hindsight-learned one):
        # only the value head moves, so the policy that --init brought is not disturbed by a random critic
        self.vopt = torch.optim.Adam([p for n, p in self.model.named_parameters() if "value_head." in n],
                                     lr=c.lr, eps=1e-5)
        self.gen = torch.Generator(device=self.device).manual_seed(c.seed)
        self.ret_std = RunningStd()
        self.update, self.global_step, self.episode, self.seed_cursor = 0, 0, 0, 0
        # the heuristic parts of the dispatch variant keep per-environment memory: they reset with the batch
        self.staggered = c.stagger and c.variant == "joint"
        self.best = {"score": -math.inf, "update": None}
        self.history: list[dict] = []
        self.progress, self.log = progress, log
        self.run_dir = Path(c.run_dir)
        self.commit = git_commit()  # the code this run started from (a resumed run keeps its first)
        self.timing = {"simulator": 0.0, "obs_to_tensor": 0.0, "forward": 0.0, "update": 0.0}
        if c.init and resume is None:
            start = load_checkpoint(c.init, str(self.device))
            if start["model_config"] != self.mcfg.to_dict():
                raise ValueError(f"--init {c.init!r}: its network ({start['model_config']}) is not this run's "
                                 f"--model {c.model} / --variant {c.variant} / --agents {c.agents}")
            self.model.load_state_dict(start["model"])
        if resume is not None:
            self._load(resume)
        self.net = torch.compile(self.model) if (c.compile and self.cuda) else self.model
        self._new_episode()

    # -- environments -------------------------------------------------------------------------
    def _take_seeds(self, k: int) -> list[int]:
        """The next ``k`` seeds of the ``train`` set for this run (a window per run seed, then onwards)."""
        train = SEED_SETS["train"]
        start = (self.cfg.seed * 1_000_003 + self.seed_cursor) % (len(train) - k)
        self.seed_cursor += k
        return list(train[start:start + k])

    def _new_episode(self) -> None:
        self.sim = Simulator(self.scenario, self._take_seeds(self.cfg.num_envs), keep_series=False, threads=1)
        self.obs = self.sim.reset()
        # staggered episodes: environment b's first episode is cut after (b + 1) / B of the horizon, so
        # that from then on the environments are spread over the whole episode
        H, B = self.scenario.horizon, self.sim.B
        self.cut = (H * (np.arange(B) + 1)) // B if self.staggered else np.full(B, H)
        self.helper = None
        if self.cfg.variant == "dispatch":  # the heuristic workforce and positioning it is trained with
            self.helper = policies.Composite("none", "threshold", "spatial")
            self.helper.reset(self.sim.seeds)
        self.state = self.model.initial_state(self.sim.B, self.device)
        self.starts = torch.ones(self.sim.B, device=self.device)
        self.ret = np.zeros(self.sim.B)

    def _autocast(self):
        return torch.autocast(device_type=self.device.type, dtype=torch.bfloat16, enabled=self.cuda and self.cfg.bf16)

    def _reward(self, nsw: np.ndarray) -> np.ndarray:
        if self.cfg.variant == "dispatch":
            last = self.sim.state.last
            nsw = np.sqrt(np.clip(last[:, _K_UPUR] * last[:, _K_UAFD], 0.0, None))
        return (nsw - self.cfg.reward_offset) * self.cfg.reward_scale

    # -- agents -------------------------------------------------------------------------------
    def agent_log_probs(self, out: dict, x: dict, acts: dict):
        """Log-probabilities (rows, A) per agent (joint: A = 1, the sum over heads), entropy (rows,), per head."""
        heads = head_log_prob_entropy(out, x, acts)
        logp = torch.stack([sum(heads[h][0] for h in hs) for hs in self.agents.values()], -1)
        ent = sum(e for _, e in heads.values())
        return logp, ent, {k: e for k, (_, e) in heads.items()}

    @staticmethod
    def values(out: dict) -> torch.Tensor:
        """The critics' values (rows, A): the joint network's one or one per independent agent."""
        v = out["value"].float()
        return v if v.dim() == 2 else v[:, None]

    # -- rollout ------------------------------------------------------------------------------
    def rollout(self) -> dict:
        c, dev, B, T = self.cfg, self.device, self.sim.B, self.cfg.num_steps
        M, N = self.sim.M, self.sim.N
        buf: dict = {k: [] for k in ("raw", "starts", "dispatch", "workforce", "positioning", "logp", "value",
                                     "reward", "done")}
        init_state = tuple(s.clone() for s in self.state)
        episodes = []
        for _ in range(T):
            t0 = time.perf_counter()
            raw = obs_to_torch(self.obs, dev)
            x = featurize(raw, self.mcfg.coord_scale)
            t1 = time.perf_counter()
            with torch.no_grad(), self._autocast():
                out, self.state = self.net(x, self.state, self.starts[None])
            noise = {k: gumbel(s, self.gen, dev) for k, s in noise_shapes(B, M, N).items()}
            acts = sample(out, x, noise)
            logp, _, _ = self.agent_log_probs(out, x, acts)
            action = env_action(acts, M)  # the dispatch variant's network has the dispatch head only
            t2 = time.perf_counter()
            if self.helper is not None:
                h = self.helper.act(self.obs)
                action["workforce"], action["positioning"] = h["workforce"], h["positioning"]
            buf["raw"].append(raw)
            buf["starts"].append(self.starts)
            for k in ("dispatch", "workforce", "positioning"):
                buf[k].append(acts.get(k, torch.zeros(B, dtype=torch.long, device=dev)))
            buf["logp"].append(logp)
            buf["value"].append(self.values(out))
            nsw, self.obs = self.sim.step_observe(action)
            reward = self._reward(nsw)
            ended = self.sim.dones | (self.sim.state.t >= self.cut)  # (B,) episodes over after this step
            self.global_step += B
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
                if ended.all() and not self.staggered:
                    self._new_episode()
                else:  # partial reset onto fresh training seeds
                    idx = np.flatnonzero(ended)
                    self.obs = self.sim.reset(indices=idx, seeds=self._take_seeds(len(idx)))
                    self.cut[idx] = self.scenario.horizon
                    self.state = tuple(s * torch.as_tensor(~ended, dtype=s.dtype, device=dev).view(1, -1, 1)
                                       for s in self.state)
            self.starts = torch.as_tensor(ended, dtype=torch.float32, device=dev)
            t3 = time.perf_counter()
            self.timing["obs_to_tensor"] += t1 - t0
            self.timing["forward"] += t2 - t1
            self.timing["simulator"] += t3 - t2
        t0 = time.perf_counter()
        with torch.no_grad(), self._autocast():
            x = featurize(obs_to_torch(self.obs, dev), self.mcfg.coord_scale)
            out, _ = self.net(x, self.state, self.starts[None])
            next_value = self.values(out)
        self.timing["forward"] += time.perf_counter() - t0
        roll = {k: torch.stack(v) for k, v in buf.items() if k != "raw"}
        roll["raw"] = {k: torch.stack([r[k] for r in buf["raw"]]) for k in OBS_KEYS}
        roll["init_state"] = init_state
        # GAE per agent (values (T, B, A); the agents share the reward); done[t] ends the episode after
        # step t (no bootstrap across it)
        adv = torch.zeros_like(roll["value"])
        last = torch.zeros_like(next_value)
        for t in reversed(range(T)):
            nv = next_value if t == T - 1 else roll["value"][t + 1]
            nonterminal = 1.0 - roll["done"][t][:, None]
            delta = roll["reward"][t][:, None] + c.gamma * nv * nonterminal - roll["value"][t]
            last = delta + c.gamma * c.gae_lambda * nonterminal * last
            adv[t] = last
        roll["adv"], roll["ret"] = adv, adv + roll["value"]
        roll["episodes"] = episodes
        return roll

    # -- update -------------------------------------------------------------------------------
    def learn(self, roll: dict) -> dict:
        c, B = self.cfg, self.sim.B
        t0 = time.perf_counter()
        stats: dict[str, list] = {k: [] for k in ("pg_loss", "v_loss", "entropy", "approx_kl", "clipfrac",
                                                  "ent_dispatch", "ent_workforce", "ent_positioning")}
        mb = B // c.minibatches
        perm_gen = torch.Generator().manual_seed(c.seed * 7919 + self.update)
        for _ in range(c.epochs):
            perm = torch.randperm(B, generator=perm_gen).to(self.device)
            for i in range(c.minibatches):
                idx = perm[i * mb:(i + 1) * mb]
                raw = {k: v[:, idx].flatten(0, 1) for k, v in roll["raw"].items()}
                x = featurize(raw, self.mcfg.coord_scale)
                acts = {k: roll[k][:, idx].flatten(0, 1) for k in ("dispatch", "workforce", "positioning")}
                state = tuple(s[:, idx] for s in roll["init_state"])
                with self._autocast():
                    out, _ = self.net(x, state, roll["starts"][:, idx])
                acts = {k: v for k, v in acts.items() if k in out or (k == "workforce" and "positioning" in out)}
                # (rows, A): one column per agent, each with its own ratio, advantage and critic; the
                # losses are summed over the agents (independent networks: independent gradients)
                logp, ent, parts = self.agent_log_probs(out, x, acts)
                old_logp = roll["logp"][:, idx].flatten(0, 1)
                adv = roll["adv"][:, idx].flatten(0, 1)
                adv = (adv - adv.mean(0)) / (adv.std(0) + 1e-8)
                ratio = (logp - old_logp).exp()
                pg = torch.max(-adv * ratio, -adv * ratio.clamp(1 - c.clip, 1 + c.clip)).mean(0).sum()
                value = self.values(out)
                old_v, ret = roll["value"][:, idx].flatten(0, 1), roll["ret"][:, idx].flatten(0, 1)
                v_clipped = old_v + (value - old_v).clamp(-c.vf_clip, c.vf_clip)
                v_loss = 0.5 * torch.max((value - ret) ** 2, (v_clipped - ret) ** 2).mean(0).sum()
                entropy = ent.mean()
                if self.update < c.value_warmup:  # the critic alone, unclipped: it starts far from the returns
                    loss, opt = 0.5 * ((value - ret) ** 2).mean(0).sum(), self.vopt
                else:
                    loss, opt = pg + c.vf_coef * v_loss - c.ent_coef * entropy, self.opt
                opt.zero_grad(set_to_none=True)
                self.opt.zero_grad(set_to_none=True)
                loss.backward()
                for group in self.clip_groups:
                    torch.nn.utils.clip_grad_norm_(group, c.max_grad_norm)
                opt.step()
                with torch.no_grad():
                    log_ratio = logp - old_logp
                    stats["approx_kl"].append(float(((ratio - 1) - log_ratio).mean()))
                    stats["clipfrac"].append(float(((ratio - 1).abs() > c.clip).float().mean()))
                stats["pg_loss"].append(pg.item())
                stats["v_loss"].append(v_loss.item())
                stats["entropy"].append(entropy.item())
                for k, v in parts.items():
                    stats[f"ent_{k}"].append(v.mean().item())
        self.timing["update"] += time.perf_counter() - t0
        return {k: float(np.mean(v)) for k, v in stats.items() if v}

    # -- evaluation and checkpoints -------------------------------------------------------------
    def policy(self, mode: str = "sample"):
        return deployable(self.model, self.cfg.variant, mode, name=f"ppo-{self.cfg.variant}")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        return score_public(self.policy, self.scenario, self.cfg.eval_seeds)

    def checkpoint(self) -> dict:
        return policy_checkpoint(self.model, self.mcfg, self.cfg.variant, self.scenario.name, self.cfg,
                                 update=self.update, global_step=self.global_step, episode=self.episode,
                                 seed_cursor=self.seed_cursor, git_commit=self.commit, best=self.best,
                                 history=self.history)

    def save(self, path: Path, full: bool = True) -> Path:
        ckpt = self.checkpoint()
        if full:  # what --resume needs on top of the policy
            ckpt["optimizer"] = self.opt.state_dict()
            ckpt["value_optimizer"] = self.vopt.state_dict()
            ckpt["ret_std"] = vars(self.ret_std)
            ckpt["generator"] = self.gen.get_state()
            ckpt["torch_rng"] = torch.get_rng_state()
        return save_atomic(ckpt, path)

    def _load(self, path) -> None:
        ckpt = load_checkpoint(path, str(self.device))
        if "optimizer" not in ckpt:
            raise ValueError(f"checkpoint {str(path)!r} has no optimizer state: it cannot be resumed")
        if ckpt["model_config"] != self.mcfg.to_dict() or ckpt["variant"] != self.cfg.variant:
            raise ValueError(f"checkpoint {str(path)!r} is a {ckpt['variant']} run of another model; "
                             "resume with the settings of its config.json")
        self.model.load_state_dict(ckpt["model"])
        self.opt.load_state_dict(ckpt["optimizer"])
        if "value_optimizer" in ckpt:
            self.vopt.load_state_dict(ckpt["value_optimizer"])
        self.ret_std.__dict__.update(ckpt["ret_std"])
        self.gen.set_state(ckpt["generator"].cpu())  # a generator state is a CPU ByteTensor, on any device
        torch.set_rng_state(ckpt["torch_rng"].cpu())
        self.update, self.global_step, self.episode = ckpt["update"], ckpt["global_step"], ckpt["episode"]
        self.seed_cursor = ckpt.get("seed_cursor", 0)
        self.commit = ckpt.get("git_commit", self.commit)
        self.best, self.history = ckpt["best"], ckpt["history"]

    # -- the loop -----------------------------------------------------------------------------
    def train(self, updates: int | None = None) -> dict:
        """Train until ``cfg.steps`` environment steps (or ``updates`` more updates); returns the last stats."""
        c = self.cfg
        per_update = c.num_envs * c.num_steps
        total_updates = math.ceil(c.steps / per_update)
        stop = total_updates if updates is None else min(total_updates, self.update + updates)
        write_run_config(self.run_dir, c, self.model, self.mcfg, self.device, self.commit)
        stats: dict = {}
        start, start_step = time.perf_counter(), self.global_step
        with RunOutputs(self, "update", f"ppo {c.variant} {self.scenario.name}", stop * per_update,
                        self.update * per_update) as out:
            while self.update < stop:
                roll = self.rollout()
                stats = self.learn(roll)
                self.update += 1
                sps = (self.global_step - start_step) / (time.perf_counter() - start)
                out.episodes(roll["episodes"])
                out.scalars("loss", stats)
                out.scalars("charts", {"env_steps_per_s": sps, "reward_std": self.ret_std.std})
                if c.eval_every and self.update % c.eval_every == 0:
                    res = self.evaluate_public()
                    self.history.append({"update": self.update, "global_step": self.global_step, **res})
                    out.public(res, self.update)
                if self.update % c.checkpoint_every == 0:
                    out.checkpoint(f"update_{self.update:06d}.pt")
                out.advance(per_update, {"sps": f"{sps:.0f}"})
        return stats
