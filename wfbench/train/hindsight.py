"""Hindsight learning: the joint model trained by imitation of the hindsight oracle, DAgger-style (one file).

After Sinclair et al. (ICML 2023): on training seeds the oracle's
:class:`~wfbench.policies.oracle.planner.Planner` (``teacher``) labels every state the episode
visits, while each environment follows the label with probability ``beta_i`` and the network
otherwise; the labels go into a FIFO dataset and the network is fitted to them by masked
log-likelihood per head. ``workforce_target`` and ``value_rollout`` learn the workforce head
from hindsight action values instead. :class:`Trainer` is the entry point; checkpoints load as
``hindsight:RUN/best.pt``. The loop, the shadow simulator, the labels and the settings:
``docs/hindsight-learning.md``; the scale-free network's k-nearest labels: ``docs/rl.md``.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from wfbench.core.fork import copy_state, fork, fork_index
from wfbench.core.kpis import SCORE
from wfbench.core.simulator import Simulator
from wfbench.policies.composite import Composite
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.dist import env_action, gumbel, log_prob_entropy, positioning_weights
from wfbench.policies.neural.model import OBS_KEYS
from wfbench.policies.oracle.oracles import OracleDispatch, OraclePositioning, OracleWorkforce
from wfbench.policies.oracle.planner import Planner
from wfbench.train.checkpoints import init_weights, load_run, run_checkpoint, save_run
from wfbench.train.collection import episode_kpis, policy_step, take_seeds
from wfbench.train.config import DECISIONS, BaseConfig, build_model, check_ints, check_numbers
from wfbench.train.outputs import RunOutputs
from wfbench.train.precision import autocast
from wfbench.train.record import start_run, write_run_config
from wfbench.train.scoring import deployable, score_public
from wfbench.train.worlds import FACILITY_KEYS, PERSONNEL_KEYS, WorldSet

VARIANTS = ("joint",)
# the teachers: the full oracle, or the oracle's workforce and positioning beside nearest-first dispatch
# (stateless, so its action in the learner's state is exact; the oracle's dispatch uses knowledge of the
# next repair outcome that no observation carries, and imitating it without that knowledge costs downtime)
TEACHERS = ("oracle", "nearest+oracle+oracle")
HEADS = DECISIONS
ROLLOUT_MODES = ("sample", "greedy")
# what the workforce head learns: the teacher's action, or the hindsight value of each of its actions
WORKFORCE_TARGETS = ("action", "values", "improve")
# which parameters train: all of them, or only the heads of the decisions with a weight > 0
TRAIN_PARAMS = ("all", "heads")
# who rolls the workforce actions forward for their values: the planner's base kernels, or the learner itself
VALUE_ROLLOUTS = ("planner", "learner")
# the parameters of each decision's head in WorkforceNet, and in the scale-free network (observation version 2)
HEAD_MODULES = {"dispatch": ("ptr_q", "ptr_k", "ptr_noop", "dist_scale"), "workforce": ("wf_head",),
                "positioning": ("pos_head",)}
SCALEFREE_HEAD_MODULES = {"dispatch": ("ptr_q", "ptr_mem", "ptr_k", "pair", "noop", "alpha"),
                          "workforce": ("wf_head",), "positioning": ("pos_mem", "pos_head")}


@dataclass
class HindsightConfig(BaseConfig):
    """Every setting of a run (the shared ones in :class:`wfbench.train.config.BaseConfig`)."""

    variant: str = "joint"  # the teacher gives all three decisions
    model: str = "cpu"  # wfbench.policies.neural.model.PRESETS, or "scalefree" (`wfbench train`'s default)
    steps: int = 200_000  # environment steps collected in all (B per simulator step)
    num_envs: int = 16  # B
    num_steps: int = 32  # T: steps per stored sequence
    checkpoint_every: int = 1  # iterations
    eval_every: int = 2  # iterations; 0: never
    run_dir: str = "runs/hindsight"
    teacher: str = "nearest+oracle+oracle"  # TEACHERS (docs/hindsight-learning.md: the better plain policy)
    iter_steps: int = 4096  # environment steps collected per DAgger iteration (rounded up to whole chunks)
    burn_in: int = 8  # first steps of a sequence that only warm up the LSTM (no loss)
    beta0: float = 1.0  # probability of the oracle's action at iteration 0
    beta_decay: float = 0.3  # beta_i = beta0 * beta_decay ** i
    rollout_mode: str = "sample"  # the learner's actions while collecting: sample | greedy
    dataset_steps: int = 100_000  # cap of the aggregated dataset (oldest sequences dropped first)
    grad_steps: int = 50  # Adam steps per iteration
    batch_seqs: int = 32  # sequences per minibatch
    lr: float = 1e-3
    max_grad_norm: float = 1.0
    dispatch_weight: float = 1.0  # weights of each head's negative log-likelihood
    workforce_weight: float = 1.0
    positioning_weight: float = 1.0
    workforce_target: str = "action"  # WORKFORCE_TARGETS (docs/hindsight-learning.md, "Hindsight action values")
    improve_temperature: float = 1.0  # "improve": target pi_old * exp(A / temperature), A in standard deviations
    train_params: str = "all"  # TRAIN_PARAMS: "heads" freezes the encoder, memory and the unweighted heads
    value_rollout: str = "planner"  # VALUE_ROLLOUTS: what acts after each workforce action in its roll-forward
    value_horizon: int = 60  # "learner": steps of each roll-forward, the action's step included
    value_every: int = 10  # "learner": steps between two scored states
    value_samples: int = 1  # "learner": roll-forwards per action (common noise across the actions)
    oracle: dict = field(default_factory=dict)  # Planner settings (dispatch_horizon, workforce_every, ...)
    scalefree_ok = True  # hindsight learning trains the scale-free network (--model scalefree), as PPO does

    @property
    def chunk_steps(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def chunks_per_iter(self) -> int:
        return math.ceil(self.iter_steps / self.chunk_steps)

    @property
    def iterations(self) -> int:
        return math.ceil(self.steps / (self.chunks_per_iter * self.chunk_steps))

    def check(self) -> None:
        if self.variant not in VARIANTS:
            raise ValueError(f"variant {self.variant!r} is not allowed; allowed: {', '.join(VARIANTS)} "
                             "(the oracle teaches all three decisions)")
        self.check_teacher()
        if self.workforce_target not in WORKFORCE_TARGETS:
            raise ValueError(f"workforce_target {self.workforce_target!r} is not allowed; allowed: "
                             f"{', '.join(WORKFORCE_TARGETS)}")
        if not self.improve_temperature > 0.0:
            raise ValueError(f"improve_temperature = {self.improve_temperature!r} is not allowed; "
                             "allowed: a number > 0")
        if self.value_rollout not in VALUE_ROLLOUTS:
            raise ValueError(f"value_rollout {self.value_rollout!r} is not allowed; allowed: "
                             f"{', '.join(VALUE_ROLLOUTS)}")
        if self.value_rollout == "learner" and self.workforce_target == "action":
            raise ValueError("value_rollout 'learner' is not allowed with workforce_target 'action' (it computes "
                             "action values); allowed: workforce_target values or improve")
        if self.workforce_target != "action" and not self.workforce_weight > 0.0:
            raise ValueError(f"workforce_target {self.workforce_target!r} with workforce_weight = "
                             f"{self.workforce_weight!r} is not allowed (the values would be computed and not "
                             "used); allowed: workforce_weight > 0, or workforce_target action")
        if self.train_params not in TRAIN_PARAMS:
            raise ValueError(f"train_params {self.train_params!r} is not allowed; allowed: {', '.join(TRAIN_PARAMS)}")
        if self.rollout_mode not in ROLLOUT_MODES:
            raise ValueError(f"rollout_mode {self.rollout_mode!r} is not allowed; allowed: {', '.join(ROLLOUT_MODES)}")
        check_ints(self, ("iter_steps", "dataset_steps", "grad_steps", "batch_seqs", "value_horizon",
                                  "value_every", "value_samples"))
        if type(self.burn_in) is not int or not 0 <= self.burn_in < self.num_steps:
            raise ValueError(f"burn_in = {self.burn_in!r} is not allowed; allowed: an integer in "
                             f"0..num_steps - 1 = {self.num_steps - 1}")
        check_numbers(self, ("beta0", "beta_decay"), lambda v: 0.0 <= v <= 1.0, "a number in [0, 1]")
        check_numbers(self, ("lr", "max_grad_norm"), lambda v: v > 0.0, "a number > 0")
        weights = [getattr(self, f"{h}_weight") for h in HEADS]
        if any(not w >= 0.0 for w in weights) or sum(weights) <= 0.0:
            raise ValueError(f"head weights {dict(zip(HEADS, weights, strict=True))} are not allowed; allowed: "
                             "numbers >= 0, at least one > 0")
        if self.dataset_steps < self.chunk_steps:
            raise ValueError(f"dataset_steps = {self.dataset_steps} is not allowed; allowed: at least one chunk, "
                             f"num_envs x num_steps = {self.chunk_steps}")
        self.check_teacher_settings()

    def check_teacher(self) -> None:
        """The teacher's name (checked first): one of :data:`TEACHERS`."""
        if self.teacher not in TEACHERS:
            raise ValueError(f"teacher {self.teacher!r} is not allowed; allowed: {', '.join(TEACHERS)}")

    def check_teacher_settings(self) -> None:
        """The teacher's settings (checked last): the planner names what it does not allow."""
        teacher_planner(self.teacher, self.oracle)


def teacher_planner(teacher: str, settings: dict) -> Planner:
    """The planner of the teacher composite (built as the registry builds it), deciding its oracle parts.

    Its ``act`` returns the joint action of the whole composite: the built-in dispatch
    of ``nearest+oracle+oracle`` is the kernel's action, which the planner models exactly.
    """
    if teacher not in TEACHERS:
        raise ValueError(f"teacher {teacher!r} is not allowed; allowed: {', '.join(TEACHERS)}")
    dispatch = OracleDispatch(**settings) if teacher == "oracle" else "nearest"
    comp = Composite(dispatch, OracleWorkforce(**settings), OraclePositioning(**settings), name=teacher)
    return comp.parts["workforce"].planner


def oracle_labels(label: dict[str, np.ndarray], obs: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    """The oracle's joint action as the network's heads express it, and the count of sanitized dispatch picks.

    Returns dispatch (B, M) int64 (N: nobody), workforce (B,) int64, positioning (B, 2)
    int64 (per row the active facility of largest weight, the first active one when the
    row has no weight on any) and the number of dispatch picks the masks forbid (made the no-op).
    """
    d = np.array(label["dispatch"], dtype=np.int64, copy=True)
    B, M = d.shape
    N = obs["personnel"].shape[1]
    rows, facs = np.nonzero(d < N)
    people = d[rows, facs]
    ok = (obs["requesting"][rows, facs] > 0) & (obs["dispatchable"][rows, people] > 0)
    # the same person named twice in one environment: only the first (slot order) counts, as in the simulator
    key = rows * (N + 1) + people
    first = np.zeros(len(key), dtype=bool)
    first[np.unique(key, return_index=True)[1]] = True
    bad = ~(ok & first)
    d[rows[bad], facs[bad]] = N
    w = np.asarray(label["workforce"], dtype=np.int64).copy()
    fac = obs["facility_mask"][:, None, :] > 0
    weights = np.where(fac, np.asarray(label["positioning"], dtype=np.float64), -1.0)
    p = weights.argmax(-1).astype(np.int64)  # (B, 2)
    return d, w, p, int(bad.sum())


def outside_candidates(x: dict[str, torch.Tensor], labels: torch.Tensor) -> torch.Tensor:
    """(B, M) bool: the choosing facilities whose dispatch label names someone outside their k candidates.

    ``x``: the scale-free network's features (:func:`wfbench.policies.neural.scalefree.featurize`),
    ``labels`` (B, M) people (N: nobody). The network cannot pick such a person, so the
    imitation loss leaves these labels out (:func:`scalefree_label_log_probs`) and the log counts them.
    """
    named = (labels < x["per_in"].shape[-2]) & x["choose"]
    among = ((x["cand"] == labels[..., None]) & x["cand_valid"]).any(-1)
    return named & ~among


def scalefree_label_log_probs(model, out: dict, x: dict, acts: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Per head, the log-probability (rows,) of the labels under the scale-free network's distributions.

    Dispatch: the sum over the choosing facilities of each row, without the labels outside
    their k candidates (:func:`outside_candidates`: no candidate list expresses them).
    """
    heads = scalefree.head_log_probs(model, out, x, acts)
    lp, fits = model.dispatch_label_log_probs(out, x, acts["dispatch"])
    rows = x["choose"].nonzero(as_tuple=True)[0]
    dispatch = lp.new_zeros(x["choose"].shape[0]).index_add(0, rows, lp * fits)
    return {"dispatch": dispatch, "workforce": heads["workforce"][0], "positioning": heads["positioning"][0]}


class Dataset:
    """The aggregated sequences: a FIFO ring of at most ``capacity`` sequences of T steps (CPU tensors)."""

    def __init__(self, capacity: int, T: int):
        self.capacity, self.T = capacity, T
        self.size, self.next = 0, 0
        self.data: dict[str, torch.Tensor] | None = None

    def add(self, chunk: dict[str, torch.Tensor]) -> None:
        """``chunk``: tensors with the sequences on axis 0 (S, T, ...) (``h``, ``c``: (S, H))."""
        S = next(iter(chunk.values())).shape[0]
        if self.data is None:
            self.data = {k: torch.zeros((self.capacity, *v.shape[1:]), dtype=v.dtype) for k, v in chunk.items()}
        idx = (self.next + torch.arange(S)) % self.capacity
        for k, v in chunk.items():
            self.data[k][idx] = v
        self.next = (self.next + S) % self.capacity
        self.size = min(self.size + S, self.capacity)

    def batch(self, idx: torch.Tensor, device: torch.device) -> dict[str, torch.Tensor]:
        """The sequences ``idx``, time major: (T, len(idx), ...) (``h``, ``c``: (1, len(idx), H))."""
        out = {}
        for k, v in self.data.items():
            x = v[idx].to(device)
            out[k] = x[None] if k in ("h", "c") else x.transpose(0, 1)
        return out


class Trainer:
    """A hindsight-learning run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint.

    Collection (:meth:`collect`) and the update (:meth:`learn`) alternate, one DAgger iteration each.
    The teacher of an episode comes from :meth:`teacher`; :mod:`wfbench.train.distill` is this
    loop with a deployable teacher in place of the oracle's planner.
    """

    ALGO = "hindsight"  # the checkpoints' algo key, the run's title and the policy's name

    def __init__(self, config: HindsightConfig, resume: str | Path | None = None, progress: bool = True,
                 log: bool = True, amp: str | torch.dtype | None = "auto"):
        self.run = start_run(config, progress, log, amp)
        c = config
        # the random streams of its own (the network's initial weights come from torch's, seeded by start_run)
        self.gen = torch.Generator(device=self.run.device).manual_seed(c.seed)  # the learner's sampling noise
        self.batch_gen = torch.Generator().manual_seed(c.seed * 7919 + 1)  # minibatch draws
        self.mix_rng = np.random.default_rng([c.seed, 0x4D1])  # oracle-or-learner draws
        self.value_gen = torch.Generator(device=self.run.device).manual_seed(c.seed * 7919 + 2)  # roll-forward noise
        self.model = build_model(self.run.network).to(self.run.device)
        self.obs_keys = scalefree.OBS_KEYS_V2 if scalefree.obs_version(self.model) == 2 else OBS_KEYS
        self.opt = torch.optim.Adam(self.trainable(), lr=c.lr)
        self.data = Dataset(max(c.dataset_steps // c.num_steps, c.num_envs), c.num_steps)
        self.iteration, self.episode, self.seed_cursor = 0, 0, 0
        self.timing = {"teacher": 0.0, "values": 0.0, "forward": 0.0, "simulator": 0.0, "update": 0.0,
                       "evaluate": 0.0}  # seconds; "values": the learner's roll-forwards (value_rollout learner)
        if c.init and resume is None:
            init_weights(self)
        if resume is not None:
            self._load(resume)
        self.sim = None

    def trainable(self) -> list[torch.nn.Parameter]:
        """The parameters the update trains (``train_params``); the others are frozen (requires_grad False)."""
        if self.run.config.train_params == "all":
            return list(self.model.parameters())
        modules = SCALEFREE_HEAD_MODULES if scalefree.obs_version(self.model) == 2 else HEAD_MODULES
        names = {m for h in HEADS if getattr(self.run.config, f"{h}_weight") > 0 for m in modules[h]}
        keep = []
        for name, param in self.model.named_parameters():
            param.requires_grad_(name.split(".")[0] in names)
            if param.requires_grad:
                keep.append(param)
        return keep

    # -- environments -------------------------------------------------------------------------
    def _new_episode(self) -> None:
        """Synchronized episodes: a new Simulator and teacher on the next B training seeds."""
        scenario = self.run.scenario
        if isinstance(scenario, WorldSet):  # across worlds: each episode of the batch on the next world in turn
            self.world = scenario.worlds[(self.seed_cursor // self.run.config.num_envs) % len(scenario.worlds)]
            scenario = self.world.config
        seeds = self.episode_seeds()
        self.seed_cursor += self.run.config.num_envs
        self.sim = Simulator(scenario, seeds, keep_series=False, threads=1)
        self.obs = self.sim.reset()
        self.planner = self.teacher(scenario, seeds)
        self.state = self.model.initial_state(self.sim.B, self.run.device)
        self.starts = torch.ones(self.sim.B, device=self.run.device)
        self.value_fork = None  # the copies the learner's roll-forwards run in (value_rollout "learner")

    def episode_seeds(self) -> list[int]:
        """The training seeds of the next episode batch: the run seed's window, ``seed_cursor`` seeds on."""
        return take_seeds(self.run.config.seed, self.seed_cursor, self.run.config.num_envs)

    def mix_beta(self, beta: float) -> float:
        """The probability that an environment follows the teacher at this step: the iteration's ``beta``."""
        return beta

    def teacher(self, scenario, seeds: list[int]):
        """The labeller of an episode on ``seeds``: the oracle's planner, attached to the world's trace.

        ``act(obs)`` gives its joint action, ``record(action)`` tells it what was played;
        ``workforce_values`` (the planner's) feeds the value targets.
        """
        planner = teacher_planner(self.run.config.teacher, self.run.config.oracle)
        planner.attach(scenario)
        planner.reset(seeds)
        return planner

    def beta(self, iteration: int | None = None) -> float:
        i = self.iteration if iteration is None else iteration
        return self.run.config.beta0 * self.run.config.beta_decay ** i

    # -- collection ---------------------------------------------------------------------------
    @torch.no_grad()
    def collect(self, beta: float, record_actions: bool = False) -> dict:
        """One chunk: T steps of the B environments under the mixture; returns the chunk and its statistics.

        ``record_actions`` also returns, per step, the seeds, the step and the executed
        and learner's actions (what the tests replay).
        """
        c, dev = self.run.config, self.run.device
        if self.sim is None:
            self._new_episode()
        B, T, M, N = self.sim.B, c.num_steps, self.sim.M, self.sim.N
        gen = self.gen if c.rollout_mode == "sample" else None  # None: greedy
        h0, c0 = (s[0].clone().cpu() for s in self.state)
        raws, starts, labels = [], [], {k: [] for k in HEADS}
        values, scored, logp_old = [], [], []
        stats = {"agree_dispatch": [], "agree_workforce": [], "oracle_share": [], "invalid_labels": 0,
                 "label_hires": 0, "label_releases": 0}
        scale_free = scalefree.obs_version(self.model) == 2
        if scale_free:  # the scale-free dispatch chooses among k candidates: labels outside them are not learned
            stats |= {"label_dispatches": 0, "labels_outside_k": 0}
        episodes, trail = [], []
        for _ in range(T):
            if self.sim.done:
                self._new_episode()
                M, N = self.sim.M, self.sim.N  # across worlds the next episode may be of another size
            t0 = time.perf_counter()
            raw, x, out, self.state, acts = policy_step(self.model, self.obs, self.state, self.starts,
                                                                self.model, gen, self.run.amp)
            mine = {k: v.cpu().numpy() for k, v in acts.items()}
            t1 = time.perf_counter()
            values_s = 0.0
            label = self.planner.act(self.obs)
            ld, lw, lp, bad = oracle_labels(label, self.obs)
            if c.workforce_target != "action":
                logits = out["workforce"].float().masked_fill(x["workforce_mask"] <= 0, -1e9)
                logp_old.append(torch.log_softmax(logits, -1).cpu())
                if c.value_rollout == "learner":
                    t_obs = int(self.obs["t"][0])
                    t_values = time.perf_counter()
                    v = self.learner_values(mine) if t_obs % c.value_every == 0 else None
                    values_s = time.perf_counter() - t_values
                else:
                    v = self.planner.workforce_values
                scored.append(torch.full((B,), v is not None))
                # an allowed action the planner did not score (nobody it could let go) counts as the no-op
                values.append(torch.from_numpy(np.nan_to_num(v, nan=0.0)).float() if v is not None
                              else torch.zeros((B, self.obs["workforce_mask"].shape[1])))
            t2 = time.perf_counter()
            use = self.mix_rng.random(B) < self.mix_beta(beta)  # per environment: the teacher's or the learner's
            action = {
                "dispatch": np.where(use[:, None], label["dispatch"], mine["dispatch"]),
                "workforce": np.where(use, label["workforce"], mine["workforce"]),
                "positioning": np.where(use[:, None, None], label["positioning"],
                                        positioning_weights(torch.from_numpy(mine["positioning"]), M).numpy()),
            }
            if record_actions:
                trail.append({"t": int(self.obs["t"][0]), "seeds": self.sim.seeds.copy(), "use_oracle": use,
                              "action": {k: v.copy() for k, v in action.items()},
                              "learner": {k: v.copy() for k, v in mine.items()},
                              "label": {"dispatch": ld, "workforce": lw, "positioning": lp}})
            raws.append(self._padded(raw if dev.type == "cpu" else {k: v.cpu() for k, v in raw.items()}))
            starts.append(self.starts.cpu())
            for k, v in zip(HEADS, (self._padded_dispatch(ld), lw, lp), strict=True):
                labels[k].append(torch.from_numpy(v))
            if scale_free:
                choosing = x["choose"].cpu().numpy()
                named = torch.from_numpy(ld).to(dev)
                stats["label_dispatches"] += int(((named < N) & x["choose"]).sum())
                stats["labels_outside_k"] += int(outside_candidates(x, named).sum())
            else:
                choosing = x["dispatch_mask"][..., :N].any(-1).cpu().numpy()
            if choosing.any():
                stats["agree_dispatch"].append(float((mine["dispatch"] == ld)[choosing].mean()))
            stats["agree_workforce"].append(float((mine["workforce"] == lw).mean()))
            stats["oracle_share"].append(float(use.mean()))
            stats["invalid_labels"] += bad
            stats["label_hires"] += int(((lw >= 1) & (lw <= 3)).sum())
            stats["label_releases"] += int((lw >= 4).sum())
            self.planner.record(action)  # the shadow follows the episode the learner is in
            t3 = time.perf_counter()
            _, self.obs = self.sim.step_observe(action)
            self.run.global_step += B
            self.starts = torch.zeros(B, device=dev)
            if self.sim.done:
                episodes.append(episode_kpis(self.sim) | {"beta": beta})
                if isinstance(self.run.scenario, WorldSet):
                    episodes[-1][f"{SCORE}/{self.world.name}"] = episodes[-1][SCORE]
                self.episode += B
                # the LSTM state is reset through the starts flags of the next episode's first step
            t4 = time.perf_counter()
            self.timing["forward"] += t1 - t0
            self.timing["teacher"] += t2 - t1 - values_s
            self.timing["values"] += values_s
            self.timing["simulator"] += t4 - t3
        chunk = {k: torch.stack([r[k] for r in raws], 1) for k in self.obs_keys}  # (B, T, ...)
        chunk["starts"] = torch.stack(starts, 1)
        chunk["dispatch"] = torch.stack(labels["dispatch"], 1).to(torch.int16)
        chunk["workforce"] = torch.stack(labels["workforce"], 1).to(torch.int8)
        chunk["positioning"] = torch.stack(labels["positioning"], 1).to(torch.int16)
        if c.workforce_target != "action":
            chunk["wf_logp_old"] = torch.stack(logp_old, 1)  # (B, T, 7): the learner's policy when it acted
            chunk["wf_values"] = torch.stack(values, 1)  # (B, T, 7)
            chunk["wf_scored"] = torch.stack(scored, 1)  # (B, T)
        chunk["h"], chunk["c"] = h0, c0
        return {"chunk": chunk, "stats": stats, "episodes": episodes, "trail": trail}

    def _padded(self, raw: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Across worlds: the observation tensors padded to the largest world's slots (empty, masked)."""
        if not isinstance(self.run.scenario, WorldSet):
            return raw
        M, N = self.run.scenario.slots
        out = {}
        for k, v in raw.items():
            size = M if k in FACILITY_KEYS else N if k in PERSONNEL_KEYS else None
            if size is None or v.shape[1] == size:
                out[k] = v
            else:
                out[k] = v.new_zeros((v.shape[0], size, *v.shape[2:]))
                out[k][:, :v.shape[1]] = v
        return out

    def _padded_dispatch(self, d: np.ndarray) -> np.ndarray:
        """Across worlds: the dispatch labels (B, M) padded with the no-op, which becomes the batch's (column N)."""
        if not isinstance(self.run.scenario, WorldSet):
            return d
        M, N = self.run.scenario.slots
        out = np.full((d.shape[0], M), N, dtype=d.dtype)
        out[:, :d.shape[1]] = np.where(d >= self.sim.N, N, d)
        return out

    @torch.no_grad()
    def learner_values(self, mine: dict[str, np.ndarray]) -> np.ndarray:
        """Each workforce action's hindsight value under the learner's own policy, minus the no-op's: (B, A).

        The mean over the samples of :meth:`learner_scores`, minus the no-op's; NaN where the
        action is masked.
        """
        mean = self.learner_scores(mine).mean(axis=1)
        return np.where(np.asarray(self.obs["workforce_mask"], dtype=bool), mean - mean[:, :1], np.nan)

    def learner_scores(self, mine: dict[str, np.ndarray]) -> np.ndarray:
        """The sum of ``NSW_t`` of each roll-forward: (B, S, A), S = ``value_samples``.

        Every environment is copied ``A * value_samples`` times (:func:`wfbench.core.fork.fork`:
        the copies meet the same future). Copy (s, a) takes this step's learner action
        (``mine``) with workforce code ``a``, then the learner acts, sampled, for
        ``value_horizon - 1`` more steps from its memory of now; the copies of sample s
        share their Gumbel noise, so two actions differ by their consequences, not by
        the dice. A masked action is rolled as the no-op, so its score equals the no-op's.
        Called after the network acted on the current observation (``self.state`` is its
        memory after this step's input).
        """
        c, dev = self.run.config, self.run.device
        mask = np.asarray(self.obs["workforce_mask"], dtype=bool)  # (B, A)
        B, A = mask.shape
        M, N, S = self.sim.M, self.sim.N, c.value_samples
        R = A * S  # copies per environment: row b * R + s * A + a
        if self.value_fork is None:
            self.value_fork = fork(self.sim, copies=R, threads=1)
        copy_state(self.value_fork, self.sim, fork_index(B, None, R))
        codes = np.tile(np.arange(A), B * S).reshape(B, S, A)
        codes = np.where(mask[:, None, :], codes, 0).reshape(-1)  # a masked action is rolled as the no-op
        action = {"dispatch": np.repeat(mine["dispatch"], R, axis=0), "workforce": codes,
                  "positioning": np.repeat(positioning_weights(torch.from_numpy(mine["positioning"]), M).numpy(),
                                           R, axis=0)}
        state = tuple(h.repeat_interleave(R, dim=1) for h in self.state)
        starts = torch.zeros(1, B * R, device=dev)
        noise_row = torch.arange(B * S, device=dev).repeat_interleave(A)  # copies (b, s, .) share noise b * S + s
        score = np.zeros(B * R)
        for k in range(c.value_horizon):
            reward, obs = self.value_fork.step_observe(action)
            score += reward
            if k == c.value_horizon - 1 or self.value_fork.done:
                break
            x = scalefree.features(self.model, scalefree.raw_tensors(self.model, obs, dev))
            with autocast(dev, self.run.amp):
                out, state = self.model(x, state, starts)
            noise = {key: gumbel(shape, self.value_gen, dev)[noise_row]
                     for key, shape in scalefree.noise_shapes(self.model, B * S, M, N).items()}
            acts = scalefree.sample(self.model, out, x, noise)
            action = env_action(acts, M)
        return score.reshape(B, S, A)

    # -- supervised update --------------------------------------------------------------------
    def losses(self, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict[str, float]]:
        """The weighted negative log-likelihood of the labels on a time-major batch of sequences."""
        c = self.run.config
        T, S = batch["starts"].shape
        raw = {k: batch[k].flatten(0, 1) for k in self.obs_keys}
        x = scalefree.features(self.model, raw)
        with autocast(self.run.device, self.run.amp):
            out, _ = self.model(x, (batch["h"], batch["c"]), batch["starts"])
        acts = {k: batch[k].flatten(0, 1).long() for k in HEADS}
        scale_free = scalefree.obs_version(self.model) == 2
        if scale_free:
            logps = scalefree_label_log_probs(self.model, out, x, acts)
        # a step counts once the LSTM state is trustworthy: after the burn-in, or from an episode start on
        t_idx = torch.arange(T, device=batch["starts"].device)[:, None]
        valid = (t_idx >= c.burn_in) | (torch.cummax(batch["starts"], 0).values > 0)
        valid = valid.flatten().float()
        denom = valid.sum().clamp_min(1.0)
        loss = torch.zeros((), device=valid.device)
        stats = {}
        for k in HEADS:
            if k == "workforce" and c.workforce_target != "action":
                temperature = c.improve_temperature if c.workforce_target == "improve" else None
                nll = self.values_loss(out[k], x["workforce_mask"], batch, valid, temperature)
            else:
                logp = logps[k] if scale_free else log_prob_entropy({k: out[k]}, x, acts)[0]
                nll = -(logp * valid).sum() / denom
            loss = loss + getattr(c, f"{k}_weight") * nll
            stats[f"nll_{k}"] = nll.item()
        stats["loss"] = loss.item()
        return loss, stats

    @staticmethod
    def values_loss(logits: torch.Tensor, mask: torch.Tensor, batch: dict[str, torch.Tensor],
                    valid: torch.Tensor, temperature: float | None = None) -> torch.Tensor:
        """The workforce head's loss on the hindsight action values, over the valid steps the planner scored.

        A is the roll-forward score of each action minus the no-op's, divided by its
        standard deviation over the allowed actions of those steps (the scale of NSW sums
        varies with the horizon; dividing keeps the loss comparable with the other heads').

        - ``temperature`` None (``values``, Hindsight MAC): ``-sum_a pi(a | obs) A(a)``.
          Its minimum puts all the mass on the action of highest mean value in each
          observation: the hindsight-optimal choice given what the network sees, where
          the imitation of the teacher's argmax learns how often each action was best.
        - a temperature (``improve``): the cross-entropy to the target
          ``pi_old(a) exp(A(a) / temperature)`` (normalized over the allowed actions),
          ``pi_old`` the learner's distribution when it acted: a step of policy
          improvement whose size the temperature bounds (the KL-regularized
          improvement of MPO), so the policy moves towards the better actions of its
          own states without jumping to the argmax of one iteration's noisy values.
        """
        A = batch["wf_values"].flatten(0, 1).float()  # (T*S, 7)
        use = valid * batch["wf_scored"].flatten().float()
        allowed = mask > 0
        logits = logits.float().masked_fill(~allowed, -1e9)
        probs = torch.softmax(logits, -1)
        sel = allowed & (use[:, None] > 0)
        scale = A[sel].std() if sel.sum() > 1 else torch.ones(())
        A = A / scale.clamp_min(1e-6)
        if temperature is None:
            return -((probs * A).sum(-1) * use).sum() / use.sum().clamp_min(1.0)
        old = batch["wf_logp_old"].flatten(0, 1).float()
        target = torch.softmax((old + A / temperature).masked_fill(~allowed, -1e9), -1)
        logp = torch.log_softmax(logits, -1)
        ce = -(target * logp).masked_fill(~allowed, 0.0).sum(-1)
        return (ce * use).sum() / use.sum().clamp_min(1.0)

    def learn(self) -> dict:
        c = self.run.config
        t0 = time.perf_counter()
        self.model.train()
        stats: dict[str, list] = {}
        for _ in range(c.grad_steps):
            idx = torch.randint(self.data.size, (min(c.batch_seqs, self.data.size),), generator=self.batch_gen)
            loss, s = self.losses(self.data.batch(idx, self.run.device))
            self.opt.zero_grad(set_to_none=True)
            loss.backward()
            s["grad_norm"] = float(torch.nn.utils.clip_grad_norm_(self.opt.param_groups[0]["params"],
                                                                  c.max_grad_norm))
            self.opt.step()
            for k, v in s.items():
                stats.setdefault(k, []).append(v)
        self.timing["update"] += time.perf_counter() - t0
        out = {k: float(np.mean(v)) for k, v in stats.items()}
        out["first_loss"], out["last_loss"] = stats["loss"][0], stats["loss"][-1]
        return out

    @torch.no_grad()
    def dataset_loss(self, max_seqs: int = 256) -> dict[str, float]:
        """The loss on (up to) the first ``max_seqs`` stored sequences, without training."""
        idx = torch.arange(min(max_seqs, self.data.size))
        return self.losses(self.data.batch(idx, self.run.device))[1]

    # -- evaluation and checkpoints -------------------------------------------------------------
    def policy(self, mode: str = "sample"):
        return deployable(self.model, "joint", mode, name=f"{self.ALGO}-joint")

    def evaluate_public(self) -> dict:
        """Mean NSW on the public selection seeds, sampled and greedy (the score is the sampled one)."""
        t0 = time.perf_counter()
        res = score_public(self.policy, self.run.scenario, self.run.config.eval_seeds)
        self.timing["evaluate"] += time.perf_counter() - t0
        return res

    def checkpoint(self) -> dict:
        return run_checkpoint(self, self.ALGO, self.iteration, episode=self.episode,
                                      seed_cursor=self.seed_cursor)

    def save(self, path: Path, full: bool = True) -> Path:
        return save_run(self, path, full, generator=self.gen.get_state(),
                                batch_generator=self.batch_gen.get_state(), mix_rng=self.mix_rng.bit_generator.state,
                                value_generator=self.value_gen.get_state())

    def _load(self, path) -> None:
        ckpt = load_run(self, path, self.ALGO)
        self.gen.set_state(ckpt["generator"].cpu())  # a generator state is a CPU ByteTensor, on any device
        self.batch_gen.set_state(ckpt["batch_generator"].cpu())
        self.mix_rng.bit_generator.state = ckpt["mix_rng"]
        if "value_generator" in ckpt:  # runs saved before value_rollout existed have none
            self.value_gen.set_state(ckpt["value_generator"].cpu())
        self.iteration, self.episode, self.seed_cursor = ckpt["update"], ckpt["episode"], ckpt["seed_cursor"]

    # -- the loop -----------------------------------------------------------------------------
    def train(self, iterations: int | None = None) -> dict:
        """Run until the config's ``steps`` environment steps are collected, or ``iterations`` more; the last stats."""
        c = self.run.config
        stop = c.iterations if iterations is None else min(c.iterations, self.iteration + iterations)
        per_iter = c.chunks_per_iter * c.chunk_steps
        write_run_config(self.run, self.model, algo=self.ALGO)
        start, start_step = time.perf_counter(), self.run.global_step
        stats: dict = {}
        with RunOutputs(self, "iteration", f"{self.ALGO} {self.run.scenario.name}", stop * per_iter,
                                self.iteration * per_iter) as out:
            while self.iteration < stop:
                beta = self.beta()
                t_collect = time.perf_counter()
                coll: dict[str, list] = {}
                episodes = []
                for _ in range(c.chunks_per_iter):
                    res = self.collect(beta)
                    self.data.add(res["chunk"])
                    episodes += res["episodes"]
                    for k, v in res["stats"].items():
                        coll.setdefault(k, []).extend(v if isinstance(v, list) else [v])
                collect_s = time.perf_counter() - t_collect
                stats = self.learn()
                self.iteration += 1
                sps = (self.run.global_step - start_step) / (time.perf_counter() - start)
                stats |= {"beta": beta, "dataset_steps": self.data.size * c.num_steps,
                          "collect_steps_per_s": per_iter / collect_s, "env_steps_per_s": sps,
                          "invalid_labels": sum(coll["invalid_labels"]), "label_hires": sum(coll["label_hires"]),
                          "label_releases": sum(coll["label_releases"])}
                if "labels_outside_k" in coll:  # the scale-free network: dispatch labels its k candidates miss
                    stats["labels_outside_k"] = sum(coll["labels_outside_k"])
                    stats["outside_k_share"] = stats["labels_outside_k"] / max(sum(coll["label_dispatches"]), 1)
                for k in ("agree_dispatch", "agree_workforce", "oracle_share"):
                    if coll[k]:
                        stats[k] = float(np.mean(coll[k]))
                out.episodes(episodes)
                out.scalars("loss", stats, ("loss", "first_loss", "last_loss", "nll_dispatch", "nll_workforce",
                                            "nll_positioning", "grad_norm"))
                out.scalars("charts", stats, ("beta", "dataset_steps", "collect_steps_per_s", "env_steps_per_s",
                                              "invalid_labels", "agree_dispatch", "agree_workforce", "oracle_share",
                                              "label_hires", "label_releases", "labels_outside_k", "outside_k_share"))
                record = {"update": self.iteration, "global_step": self.run.global_step, "beta": beta,
                          "loss": stats["loss"], "episodes": episodes}
                if c.eval_every and self.iteration % c.eval_every == 0:
                    res = self.evaluate_public()
                    record |= res
                    out.public(res, self.iteration)
                self.run.history.append(record)
                with (self.run.dir / "history.jsonl").open("a") as fh:
                    fh.write(json.dumps({**record, **{k: v for k, v in stats.items()}, "timing": self.timing})
                             + "\n")
                if self.iteration % c.checkpoint_every == 0:
                    out.checkpoint(f"iter_{self.iteration:04d}.pt")
                out.advance(per_iter, {"sps": f"{sps:.0f}", "beta": f"{beta:.2f}", "loss": f"{stats['loss']:.3f}"})
        return stats
