"""PPO for the paper's joint model, driving the batched simulator directly (one readable file).

:class:`Trainer` runs rollouts (the :class:`~wfbench.train.collection.Collector`, staggered
episodes by partial reset for ``joint``), GAE on the shaped rewards and clipped PPO updates of
whole sequences, the LSTM rerun from each rollout's stored state. ``agents="independent"`` trains
one network and critic per decision (:class:`~wfbench.policies.neural.model.AgentSet`);
``value_warmup`` fits the value heads alone first. ``best.pt`` is chosen on public seeds. Same
code on CPU (deterministic given ``seed``) and CUDA (bf16 autocast, ``compile``, minibatches in
chunks of ``update_envs``, :mod:`wfbench.train.memory`). The loop, the rewards, the checkpoints and
the settings: ``docs/rl.md``, "The trainer" and "Independent agents".
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from wfbench import policies
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.model import agent_set_config
from wfbench.train import memory
from wfbench.train.checkpoints import init_weights, load_run, run_checkpoint, save_run
from wfbench.train.collection import Collector
from wfbench.train.config import ActorCriticConfig, build_model, check_ints, check_numbers, network_config
from wfbench.train.outputs import RunOutputs
from wfbench.train.precision import autocast
from wfbench.train.record import start_run, write_run_config
from wfbench.train.scoring import deployable, score_public

AGENTS = ("joint", "independent")
VARIANTS = {
    "joint": ("dispatch", "workforce", "positioning"),
    "dispatch": ("dispatch",),
}
REWARDS = {"joint": "nsw", "dispatch": "nsw-no-cost"}  # the variant's reward (wfbench.core.reward)


@dataclass
class TrainConfig(ActorCriticConfig):
    """Every setting of a PPO run (the shared ones in :class:`wfbench.train.config.ActorCriticConfig`)."""

    agents: str = "joint"  # AGENTS: one network for all decisions, or one per decision (independent)
    epochs: int = 2
    minibatches: int = 2
    gae_lambda: float = 0.95
    clip: float = 0.2
    vf_clip: float = 0.2
    compile: bool = False  # torch.compile of the network (any device; made for CUDA)
    value_warmup: int = 0  # first updates that fit the value head alone, the policy frozen (fine-tuning --init)
    scalefree_ok = True  # PPO trains the scale-free network (--model scalefree)
    # across worlds, 16 environments a world unless --num-envs says otherwise: 128 on suite-v1's eight training
    # worlds, the batch of the shipped scalefree-general; 32 in all would leave each world 4 environments and cost
    # twice the CPU per env-step (docs/performance.md, "Training across the training split")
    envs_per_world = 16

    def check(self) -> None:
        if self.variant not in VARIANTS:
            raise ValueError(f"variant {self.variant!r} is not allowed; allowed: {', '.join(VARIANTS)}")
        if self.agents not in AGENTS:
            raise ValueError(f"agents {self.agents!r} is not allowed; allowed: {', '.join(AGENTS)}")
        if self.agents == "independent" and self.variant != "joint":
            raise ValueError(f"agents 'independent' needs variant 'joint' (variant {self.variant!r} has one "
                             "decision, so one agent)")
        check_ints(self, ("epochs", "minibatches"))
        check_ints(self, ("value_warmup",), least=0)
        check_numbers(self, ("gae_lambda",), lambda v: 0.0 < v <= 1.0, "a number in (0, 1]")
        if self.num_envs % self.minibatches:
            raise ValueError(f"num_envs = {self.num_envs} must be a multiple of minibatches = {self.minibatches}")

    def network_config(self):
        """The network's config: one ModelConfig (joint) or one per decision (independent agents)."""
        if self.agents == "independent":
            if self.model == scalefree.ARCH:
                raise ValueError("agents 'independent' with model 'scalefree' is not allowed; allowed: agents joint "
                                 "(the scale-free network decides the three decisions together)")
            return agent_set_config(self.model, VARIANTS[self.variant], **self.model_overrides)
        return network_config(self.model, VARIANTS[self.variant], self.model_overrides)


def _rows(v: torch.Tensor, envs: torch.Tensor) -> torch.Tensor:
    """The (T, B, ...) tensor's environments ``envs``, as T * len(envs) rows, time major.

    ``index_select`` rather than ``v[:, envs]``: the same copy, about half the time of
    advanced indexing on the features of a minibatch (docs/performance.md).
    """
    return v.index_select(1, envs).flatten(0, 1)


class Trainer:
    """A PPO run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint."""

    def __init__(self, config: TrainConfig, resume: str | Path | None = None, progress: bool = True,
                 log: bool = True, amp: str | torch.dtype | None = "auto", update_envs: int | str | None = "auto"):
        self.run = run = start_run(config, progress, log, amp)
        c = config
        self.decisions = VARIANTS[c.variant]
        independent = c.agents == "independent"
        self.model = build_model(run.network, independent).to(run.device)
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
        # the heuristic parts of the dispatch variant keep per-environment memory: they reset with the batch
        self.staggered = c.stagger and c.variant == "joint"
        helper = (lambda: policies.Composite("none", "threshold", "spatial")) if c.variant == "dispatch" else None
        self.env = Collector(c, run.scenario, run.device, reward=REWARDS[c.variant], staggered=self.staggered,
                                     fresh_batches=True, helper=helper, amp=run.amp)
        self.update = 0
        self.timing = self.env.timing  # simulator, obs_to_tensor, forward (the collector's), update
        self.timing["update"] = 0.0
        if c.init and resume is None:
            init_weights(self)
        if resume is not None:
            ckpt = load_run(self, resume, "ppo")
            if "value_optimizer" in ckpt:
                self.vopt.load_state_dict(ckpt["value_optimizer"])
            self.env.restore(ckpt)
            self.update = ckpt["update"]
        self.net = torch.compile(self.model) if c.compile else self.model
        self.env.start(self.model)
        # the environments of one forward and backward pass of the update: None, the whole minibatch (on CPU,
        # and wherever it fits); on CUDA a minibatch over half the GPU's memory runs in chunks (wfbench.train.memory)
        if update_envs == "auto":
            update_envs = None
            if run.cuda:
                budget = 0.5 * torch.cuda.get_device_properties(run.device).total_memory
                update_envs = memory.update_envs(run.network, self.sim.M, self.sim.N, c.num_steps, budget)
        if update_envs is not None and (type(update_envs) is not int or update_envs < 1):
            raise ValueError(f"update_envs = {update_envs!r} is not allowed; allowed: auto, None or an integer >= 1")
        self.update_envs = update_envs

    @property
    def sim(self):
        """The collector's batched simulator."""
        return self.env.sim

    # -- agents -------------------------------------------------------------------------------
    def agent_log_probs(self, out: dict, x: dict, acts: dict):
        """Log-probabilities (rows, A) per agent (joint: A = 1, the sum over heads), entropy (rows,), per head."""
        heads = scalefree.head_log_probs(self.model, out, x, acts)
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
        """T steps of the B environments (:meth:`Collector.collect`), then GAE per agent."""
        c, T = self.run.config, self.run.config.num_steps
        roll = self.env.collect(self.net, T, lambda out, x, acts: self.agent_log_probs(out, x, acts)[0],
                                self.values, model=self.model, keep_features=True)
        self.run.global_step += T * self.sim.B
        t0 = time.perf_counter()
        with torch.no_grad(), autocast(self.run.device, self.run.amp):
            x = scalefree.features(self.model, {k: v[T] for k, v in roll["raw"].items()})
            out, _ = self.net(x, self.env.state, roll["starts"][T][None])
            next_value = self.values(out)
        self.timing["forward"] += time.perf_counter() - t0
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
        return roll

    # -- update -------------------------------------------------------------------------------
    def learn(self, roll: dict) -> dict:
        c, B = self.run.config, self.sim.B
        t0 = time.perf_counter()
        stats: dict[str, list] = {k: [] for k in ("pg_loss", "v_loss", "entropy", "approx_kl", "clipfrac",
                                                  "ent_dispatch", "ent_workforce", "ent_positioning")}
        mb = B // c.minibatches
        perm_gen = torch.Generator().manual_seed(c.seed * 7919 + self.update)
        # the features of the T steps (not the last observation) as the rollout's forward passes read them,
        # rather than once per minibatch and epoch: featurize is row by row, so a minibatch's rows are the same
        # bits either way (a rollout made without them, e.g. a test's, is featurized here)
        feats = roll.get("feats")
        if feats is None:
            with torch.no_grad():
                feats = scalefree.features(self.model, {k: v[:-1] for k, v in roll["raw"].items()})
        for _ in range(c.epochs):
            perm = torch.randperm(B, generator=perm_gen).to(self.run.device)
            for i in range(c.minibatches):
                idx = perm[i * mb:(i + 1) * mb]
                if self.update_envs is not None and self.update_envs < mb:
                    self._chunked_step(feats, roll, idx, stats)
                    continue
                x = {k: _rows(v, idx) for k, v in feats.items()}
                acts = {k: _rows(roll[k], idx) for k in ("dispatch", "workforce", "positioning")}
                state = tuple(s[:, idx] for s in roll["init_state"])
                with autocast(self.run.device, self.run.amp):
                    out, _ = self.net(x, state, roll["starts"][:-1, idx])
                if scalefree.obs_version(self.model) == 1:  # the heads this network has (the dispatch variant: one)
                    acts = {k: v for k, v in acts.items() if k in out or (k == "workforce" and "positioning" in out)}
                # (rows, A): one column per agent, each with its own ratio, advantage and critic; the
                # losses are summed over the agents (independent networks: independent gradients)
                logp, ent, parts = self.agent_log_probs(out, x, acts)
                old_logp = _rows(roll["logp"], idx)
                adv = _rows(roll["adv"], idx)
                adv = (adv - adv.mean(0)) / (adv.std(0) + 1e-8)
                ratio = (logp - old_logp).exp()
                pg = torch.max(-adv * ratio, -adv * ratio.clamp(1 - c.clip, 1 + c.clip)).mean(0).sum()
                value = self.values(out)
                old_v, ret = _rows(roll["value"], idx), _rows(roll["ret"], idx)
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

    def _chunked_step(self, feats: dict, roll: dict, idx: torch.Tensor, stats: dict) -> None:
        """One minibatch (environments ``idx``) in chunks of ``update_envs`` environments, one optimizer step.

        The loss of :meth:`learn` written as sums over the rows divided by the minibatch's
        rows, so the chunks' gradients add up to the whole minibatch's (up to the order of
        float sums); the advantages are normalized over the whole minibatch. Only the
        activations of one chunk are alive at a time (``wfbench.train.memory``).
        """
        c = self.run.config
        T = roll["starts"].shape[0] - 1
        n = idx.numel() * T
        adv_all = _rows(roll["adv"], idx)
        mean, std = adv_all.mean(0), adv_all.std(0) + 1e-8
        warm = self.update < c.value_warmup
        opt = self.vopt if warm else self.opt
        opt.zero_grad(set_to_none=True)
        self.opt.zero_grad(set_to_none=True)
        sums = {k: 0.0 for k in ("pg_loss", "v_loss", "entropy", "approx_kl", "clipfrac")}
        parts_sum: dict[str, float] = {}
        for sub in idx.split(self.update_envs):
            x = {k: _rows(v, sub) for k, v in feats.items()}
            acts = {k: _rows(roll[k], sub) for k in ("dispatch", "workforce", "positioning")}
            state = tuple(s[:, sub] for s in roll["init_state"])
            with autocast(self.run.device, self.run.amp):
                out, _ = self.net(x, state, roll["starts"][:-1, sub])
            if scalefree.obs_version(self.model) == 1:
                acts = {k: v for k, v in acts.items() if k in out or (k == "workforce" and "positioning" in out)}
            logp, ent, parts = self.agent_log_probs(out, x, acts)
            old_logp = _rows(roll["logp"], sub)
            adv = (_rows(roll["adv"], sub) - mean) / std
            ratio = (logp - old_logp).exp()
            pg = torch.max(-adv * ratio, -adv * ratio.clamp(1 - c.clip, 1 + c.clip)).sum() / n
            value = self.values(out)
            old_v, ret = _rows(roll["value"], sub), _rows(roll["ret"], sub)
            v_clipped = old_v + (value - old_v).clamp(-c.vf_clip, c.vf_clip)
            v_loss = 0.5 * torch.max((value - ret) ** 2, (v_clipped - ret) ** 2).sum() / n
            entropy = ent.sum() / n
            if warm:
                loss = 0.5 * ((value - ret) ** 2).sum() / n
            else:
                loss = pg + c.vf_coef * v_loss - c.ent_coef * entropy
            loss.backward()
            with torch.no_grad():
                sums["approx_kl"] += float(((ratio - 1) - (logp - old_logp)).sum()) / ratio.numel() * sub.numel()
                sums["clipfrac"] += float(((ratio - 1).abs() > c.clip).float().sum()) / ratio.numel() * sub.numel()
            sums["pg_loss"] += pg.item()
            sums["v_loss"] += v_loss.item()
            sums["entropy"] += entropy.item()
            for k, v in parts.items():
                parts_sum[k] = parts_sum.get(k, 0.0) + float(v.detach().sum()) / n
        for group in self.clip_groups:
            torch.nn.utils.clip_grad_norm_(group, c.max_grad_norm)
        opt.step()
        sums["approx_kl"] /= idx.numel()
        sums["clipfrac"] /= idx.numel()
        for k, v in sums.items():
            stats[k].append(v)
        for k, v in parts_sum.items():
            stats[f"ent_{k}"].append(v)

    # -- evaluation and checkpoints -------------------------------------------------------------
    def policy(self, mode: str = "sample"):
        return deployable(self.model, self.run.config.variant, mode, name=f"ppo-{self.run.config.variant}")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        return score_public(self.policy, self.run.scenario, self.run.config.eval_seeds)

    def checkpoint(self) -> dict:
        return run_checkpoint(self, "ppo", self.update, episode=self.env.episode,
                                      seed_cursor=self.env.seed_cursor)

    def save(self, path: Path, full: bool = True) -> Path:
        return save_run(self, path, full, value_optimizer=self.vopt.state_dict(), **self.env.meta())

    # -- the loop -----------------------------------------------------------------------------
    def train(self, updates: int | None = None) -> dict:
        """Train until the config's ``steps`` environment steps, or ``updates`` more updates; the last stats."""
        c = self.run.config
        per_update = c.num_envs * c.num_steps
        total_updates = math.ceil(c.steps / per_update)
        stop = total_updates if updates is None else min(total_updates, self.update + updates)
        write_run_config(self.run, self.model)
        stats: dict = {}
        start, start_step = time.perf_counter(), self.run.global_step
        with RunOutputs(self, "update", f"ppo {c.variant} {self.run.scenario.name}", stop * per_update,
                                self.update * per_update) as out:
            while self.update < stop:
                roll = self.rollout()
                stats = self.learn(roll)
                self.update += 1
                sps = (self.run.global_step - start_step) / (time.perf_counter() - start)
                out.episodes(roll["episodes"])
                out.scalars("loss", stats)
                out.scalars("charts", {"env_steps_per_s": sps, "reward_std": self.env.ret_std.std})
                out.after_update(self.update)
                out.advance(per_update, {"sps": f"{sps:.0f}"})
        return stats
