"""IMPALA for the joint model: an actor with lagging parameters, a learner with V-trace (one file).

After Espeholt et al. 2018. The network, the featurizing, the rewards, the checkpoints and the
public-seed selection are the PPO trainer's (:mod:`wfbench.train.ppo`); what differs is who acts
with which parameters and how the learner corrects for it (:func:`vtrace`). ``mode="sync"`` is
deterministic on CPU given ``seed``; ``async`` (an actor thread and a bounded queue) and Ray
actors (``address`` set, :mod:`wfbench.train.ray_actors`) are not. Checkpoints load as
``impala:RUN/best.pt``. The method, V-trace's formulas, the modes and the settings:
``docs/impala.md``.
"""

from __future__ import annotations

import copy
import math
import queue
import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from wfbench.core.config import ScenarioConfig
from wfbench.harness.backends import require_ray
from wfbench.policies.neural import scalefree
from wfbench.train.checkpoints import init_weights, load_run, run_checkpoint, save_run
from wfbench.train.collection import Collector
from wfbench.train.config import ActorCriticConfig, build_model, check_ints, check_numbers
from wfbench.train.outputs import RunOutputs
from wfbench.train.precision import autocast
from wfbench.train.record import start_run, write_run_config
from wfbench.train.scoring import deployable, score_public

MODES = ("async", "sync")
OPTIMIZERS = ("adam", "rmsprop")
# address: "" (no Ray), "local" (a Ray instance started on this machine), "auto" (the cluster this machine is in)
# or a cluster's address, "ray://HOST:PORT" (Ray client) or "HOST:PORT" (its head node)
RAY_ADDRESS = re.compile(r"local|auto|(ray://)?[^\s/]+:\d+")


@dataclass
class ImpalaConfig(ActorCriticConfig):
    """Every setting of an IMPALA run (the shared ones in :class:`wfbench.train.config.ActorCriticConfig`)."""

    variant: str = "joint"  # joint only (the paper trains joint IMPALA)
    model: str = "cpu"  # wfbench.policies.neural.model.PRESETS, or "scalefree" (the scale-free network)
    run_dir: str = "runs/impala"
    mode: str = "async"  # async: actor thread + bounded queue; sync: actor and learner in turn
    queue_size: int = 1  # async: rollouts waiting for the learner, at most
    sync_every: int = 1  # K: the actor's parameters are refreshed from the learner every K updates
    optimizer: str = "adam"  # adam | rmsprop
    rms_alpha: float = 0.99  # rmsprop's smoothing constant
    eps: float = 1e-5  # the optimizer's epsilon (the losses are means over T x B, so a small one)
    rho_bar: float = 1.0  # truncation of the importance weight in delta_t and the policy gradient
    c_bar: float = 1.0  # truncation of the trace coefficient c_t
    vtrace_lambda: float = 1.0  # c_t = lambda * min(c_bar, pi / mu)
    address: str = ""  # "": the actor thread of `mode`; else Ray actors: "local", "auto", "ray://HOST:PORT"
    ray_actors: int = 2  # with address: Ray actors, each with num_envs environments (one CPU x threads each)
    scalefree_ok = True  # IMPALA trains the scale-free network (--model scalefree), as PPO does

    def check(self) -> None:
        if self.variant != "joint":
            raise ValueError(f"variant {self.variant!r} is not allowed for impala; allowed: joint")
        if self.mode not in MODES:
            raise ValueError(f"mode {self.mode!r} is not allowed; allowed: {', '.join(MODES)}")
        if self.optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer {self.optimizer!r} is not allowed; allowed: {', '.join(OPTIMIZERS)}")
        check_ints(self, ("queue_size", "sync_every", "ray_actors"))
        check_numbers(self, ("vtrace_lambda", "rms_alpha"), lambda v: 0.0 < v <= 1.0, "a number in (0, 1]")
        check_numbers(self, ("rho_bar", "c_bar", "eps"), lambda v: v > 0.0, "a number > 0")
        if self.c_bar > self.rho_bar:
            raise ValueError(f"c_bar = {self.c_bar} > rho_bar = {self.rho_bar} is not allowed; allowed: "
                             "c_bar <= rho_bar (the paper's assumption)")
        if not isinstance(self.address, str) or (self.address and not RAY_ADDRESS.fullmatch(self.address)):
            raise ValueError(f"address {self.address!r} is not allowed; allowed: '' (no Ray), 'local', 'auto', "
                             "'ray://HOST:PORT' or 'HOST:PORT'")
        if self.address:
            if self.mode != "async":
                raise ValueError(f"mode {self.mode!r} is not allowed with address (Ray actors run beside the "
                                 "learner); allowed: async")
            require_ray(f"address {self.address!r}")


def joint_log_prob(model: nn.Module, out: dict, x: dict, acts: dict) -> tuple[torch.Tensor, torch.Tensor, dict]:
    """The joint log-probability (rows,) of stored actions, the joint entropy (rows,) and the entropy per head.

    By ``model``'s distributions (:func:`wfbench.policies.neural.scalefree.head_log_probs`);
    for a version-1 network the sums of :func:`wfbench.policies.neural.dist.log_prob_entropy`.

    Args:
        model: the network whose head outputs ``out`` are.
        out: the head outputs of ``model``'s forward on the rows of ``x``.
        x: the features of the rows.
        acts: the stored actions of the rows (``dispatch``, ``workforce``, ``positioning``).
    """
    heads = scalefree.head_log_probs(model, out, x, acts)
    logp = sum(lp for lp, _ in heads.values())
    ent = sum(e for _, e in heads.values())
    return logp, ent, {k: e for k, (_, e) in heads.items()}


def _first_rows(model: nn.Module, out: dict, x: dict, n: int) -> dict:
    """The head outputs of the first ``n`` rows of a forward (the learner's T steps, not the bootstrap step).

    A version-1 network's outputs are per row (the value left out: the log-probabilities do not
    read it). The scale-free network's ``dispatch`` has a row per choosing facility in row-major
    order, so the first ``n`` rows' are the first ``x["choose"][:n].sum()``.
    """
    if scalefree.obs_version(model) == 1:
        return {k: v[:n] for k, v in out.items() if k != "value"}
    heads = {k: v[:n] for k, v in out.items() if k != "dispatch"}
    heads["dispatch"] = out["dispatch"][:int(x["choose"][:n].sum())]
    return heads


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
    each on its own share of the training seeds and with its own random generator
    (:class:`wfbench.train.collection.Collector`, which holds the simulator, the seeds and the
    return normalizer).
    """

    def __init__(self, cfg: ImpalaConfig, scenario: ScenarioConfig, model: nn.Module, device: torch.device,
                 index: int = 0, count: int = 1, amp: str | torch.dtype | None = "auto"):
        self.cfg, self.device, self.index = cfg, device, index
        self.model = copy.deepcopy(model).eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.version = -1  # the learner update whose parameters this copy holds
        # with stagger False the B episodes end together and are reset in place (never a fresh batch)
        self.env = Collector(cfg, scenario, device, staggered=cfg.stagger, index=index, count=count, amp=amp)

    @property
    def seed_cursor(self) -> int:
        return self.env.seed_cursor

    def load(self, version: int, params: dict) -> None:
        self.model.load_state_dict(params)
        self.version = version

    def meta(self) -> dict:
        """What a checkpoint needs of the actor to resume (taken as each rollout is finished)."""
        return self.env.meta()

    def restore(self, meta: dict) -> None:
        self.env.restore(meta)

    def start(self) -> None:
        """A fresh Simulator; with ``stagger`` environment b's first episode is cut after (b + 1) / B of the horizon."""
        self.env.start(self.model)

    def rollout(self) -> dict:
        """T steps (:meth:`Collector.collect`): T + 1 observations, the bootstrap V(x_T)'s the last."""
        roll = self.env.collect(self.model, self.cfg.num_steps,
                                lambda out, x, acts: joint_log_prob(self.model, out, x, acts)[0])
        roll["version"] = self.version
        roll["actor"] = self.index
        roll["meta"] = self.meta()
        return roll


class RemoteActor:
    """The Ray path's actor: an :class:`Actor` on CPU, ``index`` of ``cfg.ray_actors``, in a Ray worker process.

    A plain class: :mod:`wfbench.train.ray_actors` makes it a Ray actor (``ray.remote``), so this
    module needs no Ray. Ray pickles ``cfg``, ``meta`` and the learner's resolved ``scenario`` to the
    worker, which builds its own network and Simulator; ``params`` arrive as a CPU state_dict from the
    learner's ``ray.put``.
    """

    def __init__(self, cfg: ImpalaConfig, index: int, meta: dict | None, scenario: ScenarioConfig):
        torch.set_num_threads(cfg.threads)
        model = build_model(cfg.network_config())
        self.actor = Actor(cfg, scenario, model, torch.device("cpu"), index, cfg.ray_actors)
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
                 log: bool = True, amp: str | torch.dtype | None = "auto"):
        self.run = start_run(config, progress, log, amp)
        c = config
        self.model = build_model(self.run.network).to(self.run.device)
        if c.optimizer == "adam":
            self.opt = torch.optim.Adam(self.model.parameters(), lr=c.lr, eps=c.eps)
        else:
            self.opt = torch.optim.RMSprop(self.model.parameters(), lr=c.lr, alpha=c.rms_alpha, eps=c.eps)
        self.update = 0
        self.lags: list[int] = []  # the policy lag of every update, in order
        self.timing = {"update": 0.0, "wait": 0.0}
        if c.init and resume is None:
            init_weights(self)
        # the thread path's actor, here; the Ray path's live in Ray workers (started by train())
        self.actor = None if c.address else Actor(c, self.run.scenario, self.model, self.run.device, amp=self.run.amp)
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

    # -- one learner step -----------------------------------------------------------------------
    def learn(self, roll: dict) -> dict:
        c = self.run.config
        t0 = time.perf_counter()
        T, B = roll["logp"].shape
        raw = {k: v.flatten(0, 1) for k, v in roll["raw"].items()}  # (T + 1) * B rows, time major
        x = scalefree.features(self.model, raw)
        with autocast(self.run.device, self.run.amp):
            out, _ = self.model(x, roll["init_state"], roll["starts"])
        values = out["value"].float().view(T + 1, B)
        n = T * B  # the last step's rows only give the bootstrap value
        heads = _first_rows(self.model, out, x, n)
        acts = {k: roll[k].flatten(0, 1) for k in ("dispatch", "workforce", "positioning")}
        logp, ent, parts = joint_log_prob(self.model, heads, {k: v[:n] for k, v in x.items()}, acts)
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
        return deployable(self.model, self.run.config.variant, mode, name=f"impala-{self.run.config.variant}")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        return score_public(self.policy, self.run.scenario, self.run.config.eval_seeds)

    def checkpoint(self) -> dict:
        """The shared checkpoint keys (``algo: impala``; ``impala:PATH`` loads it), the actors' counts summed."""
        metas = [m for m in self.actor_metas if m is not None]
        # episodes run and training seeds taken, all actors together
        return run_checkpoint(self, "impala", self.update, episode=sum(m["episode"] for m in metas),
                                      seed_cursor=sum(m["seed_cursor"] for m in metas))

    def save(self, path: Path, full: bool = True) -> Path:
        # each actor's return normalizer, generator and seed cursor
        return save_run(self, path, full, actors=list(self.actor_metas), lags=list(self.lags))

    def _load(self, path) -> None:
        ckpt = load_run(self, path, "impala")
        self.update, self.lags = ckpt["update"], list(ckpt.get("lags", []))
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
            return _to_device(roll, self.run.device)
        if self.run.config.mode == "sync":
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
        self._queue: queue.Queue = queue.Queue(maxsize=self.run.config.queue_size)
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
        self._ray = RayActors(self.run.config, RemoteActor, self.actor_metas, version, params,
                              (self.run.scenario,))
        self._ray.run(count)

    def _stop_actors(self) -> None:
        """Stop the actor thread, or kill the Ray actors and shut Ray down if this run started it."""
        if self.run.config.mode == "async" and hasattr(self, "_thread"):
            self._stop_actor()
            del self._thread
        if self._ray is not None:
            self._ray.close()
            self._ray = None

    # -- the loop -----------------------------------------------------------------------------
    def train(self, updates: int | None = None) -> dict:
        """Train until the config's ``steps`` environment steps, or ``updates`` more updates; the last stats."""
        c = self.run.config
        per_update = c.num_envs * c.num_steps
        total_updates = math.ceil(c.steps / per_update)
        stop = total_updates if updates is None else min(total_updates, self.update + updates)
        write_run_config(self.run, self.model, algo="impala")
        how = f"ray x{c.ray_actors}" if c.address else c.mode
        stats: dict = {}
        start, start_step = time.perf_counter(), self.run.global_step
        with RunOutputs(self, "update", f"impala {how} {self.run.scenario.name}", stop * per_update,
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
                self.run.global_step += per_update
                self.actor_metas[roll["actor"]] = roll["meta"]
                if self.update % c.sync_every == 0:
                    self.publish()
                sps = (self.run.global_step - start_step) / (time.perf_counter() - start)
                out.episodes(roll["episodes"])
                out.scalars("loss", stats)
                out.scalars("charts", {"env_steps_per_s": sps, "reward_std": roll["meta"]["ret_std"]["var"] ** 0.5,
                                       "learner_wait_s": self.timing["wait"]})
                out.after_update(self.update)
                out.advance(per_update, {"sps": f"{sps:.0f}", "lag": f"{np.mean(self.lags[-20:]):.1f}"})
        return stats
