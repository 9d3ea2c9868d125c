"""PPO for the paper's joint model, driving the batched simulator directly (one readable file).

:class:`Trainer` runs rollouts (the :class:`~wfbench.train.collection.Collector`, staggered
episodes by partial reset for ``joint``), GAE on the shaped rewards and clipped PPO updates of
whole sequences, the LSTM rerun from each rollout's stored state. ``agents="independent"`` trains
one network and critic per decision (:class:`~wfbench.policies.neural.model.AgentSet`);
``value_warmup`` fits the value heads alone first. ``best.pt`` is chosen on public seeds. Same
code on CPU (deterministic given ``seed``) and CUDA (bf16 autocast, ``compile``, minibatches in
chunks of ``update_envs``, :mod:`wfbench.train.memory`). The batch is computed as ``shards``
fixed parts (a collector each, their gradients summed), by one process or by two (data-parallel,
``torch.distributed``: :mod:`wfbench.train.shards`), with the same bits. The loop, the rewards,
the checkpoints and the settings: ``docs/rl.md``, "The trainer", "Independent agents" and
"Shards and processes".
"""

from __future__ import annotations

import math
import signal
import time
import traceback
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from wfbench import policies
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.model import agent_set_config
from wfbench.train import memory, standby
from wfbench.train.checkpoints import init_weights, load_run, run_checkpoint, save_run
from wfbench.train.collection import Collector
from wfbench.train.config import ActorCriticConfig, build_model, check_ints, check_numbers, network_config
from wfbench.train.outputs import RunOutputs
from wfbench.train.precision import autocast
from wfbench.train.record import start_run, write_run_config
from wfbench.train.scoring import deployable, score_public
from wfbench.train.shards import ShardGroup, Worker, receive, send
from wfbench.train.standby import AUTO_SHARD_ENVS, usable_cores
from wfbench.train.worlds import world_set

AGENTS = ("joint", "independent")
VARIANTS = {
    "joint": ("dispatch", "workforce", "positioning"),
    "dispatch": ("dispatch",),
}
REWARDS = {"joint": "nsw", "dispatch": "nsw-no-cost"}  # the variant's reward (wfbench.core.reward)
STATS = ("pg_loss", "v_loss", "entropy", "approx_kl", "clipfrac", "ent_dispatch", "ent_workforce", "ent_positioning")
HEADS = ("dispatch", "workforce", "positioning")


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
    # the batch computed as this many fixed shards, a collector each, their gradients summed (wfbench.train.shards):
    # 0 (auto) is 2 from AUTO_SHARD_ENVS environments on when they split evenly, else 1; the weights depend on it
    shards: int = 0
    # the processes computing the shards: 0 (auto) is one per shard on a CPU with 2 cores or more, else 1; 1 and 2
    # train the same bits (docs/rl.md, "Shards and processes")
    procs: int = 0

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
        if type(self.shards) is not int or self.shards not in (0, 1, 2):
            raise ValueError(f"shards = {self.shards!r} is not allowed; allowed: 0 (auto), 1 or 2")
        if self.shards == 2 and (self.num_envs % (2 * self.minibatches) or self.num_envs // 2 < self._worlds()):
            raise ValueError(f"shards = 2 with num_envs = {self.num_envs}: each shard takes half of every minibatch "
                             f"and of every world's environments; allowed: num_envs a multiple of 2 x minibatches = "
                             f"{2 * self.minibatches} and at least 2 x worlds = {2 * self._worlds()}, or shards 1")
        if type(self.procs) is not int or self.procs not in (0, 1, 2):
            raise ValueError(f"procs = {self.procs!r} is not allowed; allowed: 0 (auto), 1 or 2")
        if self.procs == 2 and self.shard_count() == 1:
            raise ValueError(f"procs = 2 with one shard (num_envs = {self.num_envs}, shards = {self.shards}) is not "
                             f"allowed; allowed: procs 0 (auto) or 1, or shards 2 (num_envs a multiple of "
                             f"{2 * self.minibatches}, at least {AUTO_SHARD_ENVS} for auto)")
        if self.procs == 2 and not self._on_cpu():
            raise ValueError(f"procs = 2 runs on the CPU only (device {self.device!r}); allowed: procs 0 (auto) or "
                             "1, or device cpu")

    def _worlds(self) -> int:
        return len(world_set(self.scenarios).worlds) if self.scenarios else 1

    def _on_cpu(self) -> bool:
        return self.device == "cpu" or (self.device == "auto" and not torch.cuda.is_available())

    def shard_count(self) -> int:
        """The shards the batch is computed as: ``shards``, or for 0 (auto) 2 when the batch splits evenly, else 1."""
        if self.shards:
            return self.shards
        even = self.num_envs % (2 * self.minibatches) == 0 and self.num_envs // 2 >= self._worlds()
        return 2 if even and self.num_envs >= AUTO_SHARD_ENVS else 1

    def proc_count(self) -> int:
        """The processes: ``procs``, or for 0 (auto) one per shard on a CPU run with 2 cores or more, else 1."""
        if self.procs:
            return self.procs
        return self.shard_count() if self._on_cpu() and usable_cores() >= 2 else 1

    @classmethod
    def from_dict(cls, d: dict):
        # a run saved before shards existed was computed as one shard: it resumes (and reads) so
        return super().from_dict({"shards": 1, **d})

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
    """A PPO run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint.

    The batch is ``config.shard_count()`` shards of environments (``shards``, a
    :class:`Collector` each); this process computes ``group.local`` of them, all unless the
    run has two processes (``config.proc_count()``), when a :class:`Worker` computes shard 1
    (``rank`` 1: a trainer the worker makes; it writes nothing). ``env`` is the first local
    shard's collector. :meth:`close` (or the end of :meth:`train`'s last update) lets the worker go.
    """

    def __init__(self, config: TrainConfig, resume: str | Path | None = None, progress: bool = True,
                 log: bool = True, amp: str | torch.dtype | None = "auto", update_envs: int | str | None = "auto",
                 rank: int = 0):
        self.run = run = start_run(config, progress, log, amp)
        c = config
        self.group = group = ShardGroup(c.shard_count(), c.proc_count(), rank)
        self.worker: Worker | None = None
        if group.procs > 1 and rank == 0:  # the second process starts first: it builds its trainer meanwhile
            port = group.listen()
            self.worker = Worker("wfbench.train.ppo:serve_shard", c, resume, amp, update_envs, port)
            self._close = weakref.finalize(self, _shut, self.worker, group)
        else:  # one process: a standby started ahead for a second (wfbench train's guess) is not needed
            standby.release()
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
        # the shards this process computes: shard k is a collector of num_envs / shards environments, its own seeds
        # (every shards-th of the window), its own sampling generator and reward normalizers; one timing for all
        self.per_shard = c.num_envs // group.shards
        self.timing = {"obs_to_tensor": 0.0, "forward": 0.0, "simulator": 0.0, "update": 0.0}
        self.shards: dict[int, Collector] = {}
        for k in group.local:
            col = Collector(c, run.scenario, run.device, reward=REWARDS[c.variant], staggered=self.staggered,
                            fresh_batches=True, helper=helper, amp=run.amp, index=k, count=group.shards,
                            num_envs=self.per_shard, stagger_across=True)
            col.timing = self.timing
            self.shards[k] = col
        self.env = self.shards[group.local[0]]
        self.remote_meta: dict[int, dict] = {}  # the worker's shard: its collector's state after its last rollout
        self.heads_seen: set[str] = set()  # the heads whose entropy the last update logged
        self.update = 0
        if c.init and resume is None:
            init_weights(self)
        if resume is not None:
            ckpt = load_run(self, resume, "ppo")
            if "value_optimizer" in ckpt:
                self.vopt.load_state_dict(ckpt["value_optimizer"])
            if group.shards > 1 and "shards" not in ckpt:
                raise ValueError(f"checkpoint {str(resume)!r} holds one shard's collector; resume it with shards 1")
            for k, col in self.shards.items():
                col.restore(ckpt["shards"][k] if group.shards > 1 else ckpt)
            self.update = ckpt["update"]
        self.net = torch.compile(self.model) if c.compile else self.model
        for col in self.shards.values():
            col.start(self.model)
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
        if self.worker is not None:  # the worker's trainer is ready (or failed: its error is raised here)
            self.remote_meta = {1: self.worker.recv()}
            group.join()

    @property
    def sim(self):
        """The first local shard's batched simulator."""
        return self.env.sim

    def close(self) -> None:
        """Let the second process go (nothing to do with one); the trainer cannot collect with it after."""
        if self.worker is not None:
            self._close()
            self.worker = None

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
        """T steps of every local shard (:meth:`Collector.collect`), then GAE per agent, as one batch.

        The local shards' rollouts side by side (environment axis 1, shard order); the
        worker's shard stays in the worker, its finished episodes join ``episodes``.
        """
        if self.worker is not None:
            self.worker.send(("rollout", None))
        rolls = [self._shard_rollout(col) for col in self.shards.values()]
        roll = rolls[0] if len(rolls) == 1 else _side_by_side(rolls)
        if self.worker is not None:
            done = self.worker.recv()
            roll["episodes"] = roll["episodes"] + done["episodes"]  # shard order: this process is shard 0
            self.remote_meta = {1: done["meta"]}
        self.run.global_step += self.run.config.num_steps * self.run.config.num_envs
        return roll

    def _shard_rollout(self, col: Collector) -> dict:
        c, T = self.run.config, self.run.config.num_steps
        # in inference mode, which spares each of the step's many small operations autograd's version counters
        # and views (about a tenth of a rollout on CPU; the same bits). Its tensors (the rollout's, the collector's
        # LSTM state) are only read afterwards: the update's gathers copy them into ordinary tensors
        with torch.inference_mode():
            roll = col.collect(self.net, T, lambda out, x, acts: self.agent_log_probs(out, x, acts)[0],
                               self.values, model=self.model, keep_features=True)
            t0 = time.perf_counter()
            with autocast(self.run.device, self.run.amp):
                x = scalefree.features(self.model, {k: v[T] for k, v in roll["raw"].items()})
                out, _ = self.net(x, col.state, roll["starts"][T][None])
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
        """The PPO update: ``epochs`` x ``minibatches`` steps, each minibatch a part of every shard's environments.

        Every process draws every shard's permutation (one generator per update), so each
        knows each minibatch; the advantages are normalized over the whole minibatch (every
        shard's, gathered); each local shard's gradient of its part of the loss (sums over its
        rows / the minibatch's rows) is summed over the shards (:meth:`ShardGroup.sum`), then
        clipped, and every process takes the same step.
        """
        if self.worker is not None:
            self.worker.send(("learn", self.update))
        c, group, per = self.run.config, self.group, self.per_shard
        t0 = time.perf_counter()
        stats: dict[str, list] = {k: [] for k in STATS}
        m = per // c.minibatches  # environments of each shard in a minibatch
        perm_gen = torch.Generator().manual_seed(c.seed * 7919 + self.update)
        # the features of the T steps (not the last observation) as the rollout's forward passes read them,
        # rather than once per minibatch and epoch: featurize is row by row, so a minibatch's rows are the same
        # bits either way (a rollout made without them, e.g. a test's, is featurized here)
        feats = roll.get("feats")
        if feats is None:
            with torch.no_grad():
                feats = scalefree.features(self.model, {k: v[:-1] for k, v in roll["raw"].items()})
        adv_all = torch.cat(group.gather(list(roll["adv"].split(per, 1))), 1)  # every shard's, shard order
        warm = self.update < c.value_warmup  # the critic alone, unclipped: it starts far from the returns
        opt = self.vopt if warm else self.opt
        params = list(self.model.parameters())
        for _ in range(c.epochs):
            perms = [torch.randperm(per, generator=perm_gen).to(self.run.device) for _ in range(group.shards)]
            for i in range(c.minibatches):
                parts = [p[i * m:(i + 1) * m] for p in perms]
                adv = _rows(adv_all, torch.cat([part + k * per for k, part in enumerate(parts)]))
                norm = (adv.mean(0), adv.std(0) + 1e-8, adv.shape[0])  # over the whole minibatch's rows
                # (no zero_grad: each shard's pass sets every gradient to None first, _set_grads writes them all)
                # each local shard's gradient (zeros where a parameter has none, and whether it has one) and sums
                # of its losses: one vector each, summed over the shards
                total = group.sum([self._shard_grad(feats, roll, parts[k] + j * per, norm, warm, params)
                                   for j, k in enumerate(group.local)])
                sums = self._set_grads(total, params)
                for group_params in self.clip_groups:
                    torch.nn.utils.clip_grad_norm_(group_params, c.max_grad_norm)
                opt.step()
                for k, v in zip(STATS, sums.tolist(), strict=True):
                    if not k.startswith("ent_") or k[4:] in self.heads_seen:
                        stats[k].append(v)
        self.timing["update"] += time.perf_counter() - t0
        return {k: float(np.mean(v)) for k, v in stats.items() if v}

    def _shard_grad(self, feats: dict, roll: dict, idx: torch.Tensor, norm: tuple, warm: bool,
                    params: list) -> torch.Tensor:
        """One shard's part of a minibatch (its environments ``idx`` in ``roll``): its gradient, flags and sums, flat.

        The loss as sums over the shard's rows divided by the minibatch's ``n`` rows (of every
        shard), so the shards' gradients add up to the minibatch's; run in chunks of
        ``update_envs`` environments (their gradients accumulate), only one chunk's activations
        alive at a time (``wfbench.train.memory``).
        """
        c = self.run.config
        mean, std, n = norm
        for p in params:
            p.grad = None
        sums = torch.zeros(len(STATS), device=self.run.device)
        for sub in idx.split(self.update_envs or idx.numel()):
            x = {k: _rows(v, sub) for k, v in feats.items()}
            acts = {k: _rows(roll[k], sub) for k in HEADS}
            state = tuple(s[:, sub] for s in roll["init_state"])
            with autocast(self.run.device, self.run.amp):
                out, _ = self.net(x, state, roll["starts"][:-1, sub])
            if scalefree.obs_version(self.model) == 1:  # the heads this network has (the dispatch variant: one)
                acts = {k: v for k, v in acts.items() if k in out or (k == "workforce" and "positioning" in out)}
            # (rows, A): one column per agent, each with its own ratio, advantage and critic; the losses are
            # summed over the agents (independent networks: independent gradients)
            logp, ent, parts = self.agent_log_probs(out, x, acts)
            old_logp = _rows(roll["logp"], sub)
            adv = (_rows(roll["adv"], sub) - mean) / std
            ratio = (logp - old_logp).exp()
            pg = torch.max(-adv * ratio, -adv * ratio.clamp(1 - c.clip, 1 + c.clip)).sum(0).div(n).sum()
            value = self.values(out)
            old_v, ret = _rows(roll["value"], sub), _rows(roll["ret"], sub)
            v_clipped = old_v + (value - old_v).clamp(-c.vf_clip, c.vf_clip)
            v_loss = 0.5 * torch.max((value - ret) ** 2, (v_clipped - ret) ** 2).sum(0).div(n).sum()
            entropy = ent.sum().div(n)
            if warm:
                loss = 0.5 * ((value - ret) ** 2).sum(0).div(n).sum()
            else:
                loss = pg + c.vf_coef * v_loss - c.ent_coef * entropy
            loss.backward()
            with torch.no_grad():
                cells = n * ratio.shape[1]
                sums += torch.stack([pg, v_loss, entropy, ((ratio - 1) - (logp - old_logp)).sum() / cells,
                                     ((ratio - 1).abs() > c.clip).float().sum() / cells,
                                     *(parts[h].sum() / n if h in parts else pg.new_zeros(()) for h in HEADS)])
            self.heads_seen = set(parts)
        grads = [p.grad.reshape(-1) if p.grad is not None else p.new_zeros(p.numel()) for p in params]
        has = torch.tensor([p.grad is not None for p in params], dtype=sums.dtype, device=sums.device)
        return torch.cat([*grads, has, sums])

    def _set_grads(self, total: torch.Tensor, params: list) -> torch.Tensor:
        """Each parameter's summed gradient (None where no shard had one) from ``total``; returns the loss sums."""
        sizes = [p.numel() for p in params]
        *grads, has, sums = total.split([*sizes, len(params), len(STATS)])
        for p, g, h in zip(params, grads, has.tolist(), strict=True):
            p.grad = g.view_as(p) if h else None
        return sums

    # -- evaluation and checkpoints -------------------------------------------------------------
    def policy(self, mode: str = "sample"):
        return deployable(self.model, self.run.config.variant, mode, name=f"ppo-{self.run.config.variant}")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        return score_public(self.policy, self.run.scenario, self.run.config.eval_seeds)

    def shard_meta(self) -> list[dict]:
        """Every shard's collector state (seeds, episodes, normalizers, generator), in shard order."""
        metas = {**{k: col.meta() for k, col in self.shards.items()}, **self.remote_meta}
        return [metas[k] for k in range(self.group.shards)]

    def checkpoint(self) -> dict:
        metas = self.shard_meta()
        return run_checkpoint(self, "ppo", self.update, episode=sum(m["episode"] for m in metas),
                              seed_cursor=sum(m["seed_cursor"] for m in metas))

    def save(self, path: Path, full: bool = True) -> Path:
        """A checkpoint (rank 0's); a resume needs each shard's collector: one shard's at the top, else ``shards``."""
        metas = self.shard_meta()
        collectors = metas[0] if len(metas) == 1 else {"shards": metas}
        return save_run(self, path, full, value_optimizer=self.vopt.state_dict(), **collectors)

    # -- the loop -----------------------------------------------------------------------------
    def train(self, updates: int | None = None) -> dict:
        """Train until the config's ``steps`` environment steps, or ``updates`` more updates; the last stats."""
        c = self.run.config
        per_update = c.num_envs * c.num_steps
        total_updates = math.ceil(c.steps / per_update)
        stop = total_updates if updates is None else min(total_updates, self.update + updates)
        # shards and procs as resolved (0 is auto): the shards fix the bits, the processes the speed
        write_run_config(self.run, self.model, computed_as={"shards": self.group.shards, "procs": self.group.procs})
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
        if self.update >= total_updates:  # the run has taken its steps: the second process goes
            self.close()
        return stats


def _side_by_side(rolls: list[dict]) -> dict:
    """Shards' rollouts as one: every tensor (time first) concatenated on the environment axis, the episodes in turn."""
    def cat(values):
        v = values[0]
        if isinstance(v, dict):
            return {k: cat([x[k] for x in values]) for k in v}
        if isinstance(v, tuple):  # the LSTM state: (layers, B, H) each
            return tuple(cat([x[i] for x in values]) for i in range(len(v)))
        if isinstance(v, list):
            return [e for x in values for e in x]
        return torch.cat(values, 1)

    return cat(rolls)


def _shut(worker: Worker, group: ShardGroup) -> None:
    worker.stop()
    group.leave()  # a worker still joining fails at once without the store
    worker.wait()


def serve_shard(conn, config: TrainConfig, resume, amp, update_envs, port: int) -> None:
    """The second process of a two-process run (:class:`wfbench.train.shards.Worker`): shard 1, on command.

    It makes its trainer (``rank`` 1: the same weights, its shard's collector), says it is
    ready with its collector's state, joins the group and then does what rank 0 says:
    ``rollout`` (answered with its finished episodes and its collector's state), ``learn``
    (update number given; the gradients meet in :meth:`ShardGroup.sum`) or ``stop``.
    Ctrl-C is rank 0's to handle: this process goes when rank 0 stops it or is gone.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        tr = Trainer(config, resume, progress=False, log=False, amp=amp, update_envs=update_envs, rank=1)
    except BaseException:
        send(conn, ("error", traceback.format_exc()))
        return
    send(conn, ("ready", tr.env.meta()))
    tr.group.join(port)
    roll = None
    try:
        while True:
            try:
                cmd, arg = receive(conn)
            except EOFError:  # rank 0 is gone
                return
            if cmd == "rollout":
                try:
                    roll = tr.rollout()
                except BaseException:
                    send(conn, ("error", traceback.format_exc()))
                    return
                send(conn, ("rolled", {"episodes": roll["episodes"], "meta": tr.env.meta()}))
            elif cmd == "learn":
                tr.update = arg
                tr.learn(roll)
            else:
                return
    finally:
        tr.group.leave()
