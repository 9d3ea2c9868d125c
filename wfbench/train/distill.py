"""Distillation: the network trained to imitate a deployable teacher on its own states (DAgger, one file).

Expert iteration's second half (Anthony et al. 2017): a teacher that spends compute at decision
time (``rollout-solver-tuned``, ``search-scalefree-general``, any policy of the registry that
reads only its observations) labels every state the episode visits, while each environment
follows the teacher with probability ``beta_i`` and the network otherwise (Ross et al. 2011);
the network is fitted to the labels by masked log-likelihood per head. It is the hindsight
learner's loop (:class:`wfbench.train.hindsight.Trainer`) with the teacher swapped: the oracle
there reads the future, and its actions can be impossible without it; this teacher has no
such bias to copy. A teacher that reads the trace is refused. Labels of the teacher's own play
(``beta = 1``) do not depend on the student and are kept in a cache (:class:`LabelCache`).
Checkpoints load as ``distill:RUN/best.pt``; ``docs/rl.md``, "Distillation".
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from functools import cache
from importlib.util import find_spec
from pathlib import Path
from typing import Any

import numpy as np
import torch

from wfbench.core.actions import AGENTS
from wfbench.harness.runner import public_world
from wfbench.policies.neural import scalefree
from wfbench.train import hindsight
from wfbench.train.scoring import SELECT_MODES, score_public
from wfbench.train.worlds import WorldSet

DEFAULT_TEACHER = "rollout-solver-tuned-1ms"
HINDSIGHT_ONLY = {"workforce_target": "action", "value_rollout": "planner", "oracle": {}}  # settings it keeps
CACHE_ENV = "WFBENCH_LABEL_CACHE"  # where the teachers' labels are kept (default ~/.cache/wfbench/labels)


def reads_future(name: str, policy: Any | None = None) -> bool:
    """Whether the policy ``name`` reads the trace (an oracle of any kind): it may not teach here."""
    return name.split("#")[0].split("@")[0].startswith("oracle") or bool(getattr(policy, "reads_trace", False))


def teacher_policy(name: Any) -> Any:
    """A fresh teacher: the registry's policy ``name``, deployable and deciding all three decisions.

    Raises:
        ValueError: one line: not a name, an unknown name (the registry's own message), a
            policy that reads the future, or one that does not decide all three decisions.
    """
    from wfbench.policies import registry

    rule = ("distillation imitates a deployable teacher, one that reads only its observations; allowed: e.g. "
            f"{DEFAULT_TEACHER}, rollout-solver-tuned, search-scalefree-general (hindsight learning, --algo "
            "hindsight, is the method that imitates the oracle)")
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"teacher {name!r} is not allowed; allowed: the name of a deployable policy, e.g. "
                         f"{DEFAULT_TEACHER}")
    if reads_future(name):
        raise ValueError(f"teacher {name!r} reads the future: {rule}")
    try:
        policy = registry.get(name)
    except (ValueError, KeyError, FileNotFoundError) as exc:
        lines = str(exc).strip().splitlines()
        raise ValueError(f"teacher {name!r} is not a policy: {lines[0] if lines else type(exc).__name__}") from None
    if reads_future(name, policy):
        raise ValueError(f"teacher {name!r} reads the future: {rule}")
    decides = tuple(getattr(policy, "decisions", ()))
    if set(decides) != set(AGENTS):
        raise ValueError(f"teacher {name!r} decides {', '.join(decides) or 'nothing'}; allowed: a policy that "
                         f"decides {', '.join(AGENTS)} (the network imitates all three)")
    return policy


class Teacher:
    """A deployable policy as DAgger's labeller: it sees every observation of the episode the student is in.

    What the hindsight loop asks of its planner: ``act(obs)`` (the joint action, the label)
    and ``record(action)`` (what was played: the teacher learns it from the next
    observation, as in evaluation, so nothing is done). ``workforce_values`` is None: the
    value targets are hindsight learning's.
    """

    workforce_values = None

    def __init__(self, policy: Any, scenario, seeds: list[int]):
        self.policy = policy
        if hasattr(policy, "set_world"):
            policy.set_world(public_world(scenario))
        policy.reset(np.asarray(seeds, dtype=np.int64))

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return self.policy.act(obs)

    def record(self, action: dict[str, np.ndarray]) -> None:
        pass


class LabelCache:
    """The teacher's labels of its own play, one file per (teacher, code, world, seeds) episode batch.

    While every environment of a batch follows the teacher (``beta = 1``), the episode and
    its labels are the teacher's alone: the same for every student and every run that plays
    those seeds. :class:`CachedTeacher` replays a stored episode's labels, so the teacher's
    cost is paid once a machine. The key holds wfbench's version, the teacher's name and the
    world's public config, so a change of code or world makes a new file, never a mix.
    """

    def __init__(self, folder: str | Path | None = None):
        default = Path(os.environ.get(CACHE_ENV, "") or Path.home() / ".cache" / "wfbench" / "labels")
        self.folder = Path(folder) if folder else default

    @staticmethod
    def key(teacher: str, scenario, seeds: list[int]) -> str:
        text = json.dumps({"code": _code_digest(),
                           "teacher": teacher, "world": scenario.to_dict(), "seeds": [int(s) for s in seeds]},
                          sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    def path(self, teacher: str, scenario, seeds: list[int]) -> Path:
        return self.folder / teacher / f"{scenario.name}-{self.key(teacher, scenario, seeds)}.npz"

    def load(self, teacher: str, scenario, seeds: list[int]) -> list[dict[str, np.ndarray]] | None:
        path = self.path(teacher, scenario, seeds)
        if not path.exists():
            return None
        with np.load(path) as z:
            steps = int(z["steps"])
            return [{k: z[f"{k}_{t}"] for k in AGENTS} for t in range(steps)]

    def save(self, teacher: str, scenario, seeds: list[int], labels: list[dict[str, np.ndarray]]) -> Path:
        path = self.path(teacher, scenario, seeds)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {f"{k}_{t}": np.asarray(a[k]) for t, a in enumerate(labels) for k in AGENTS}
        tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
        np.savez_compressed(tmp, steps=np.int64(len(labels)), **arrays)
        os.replace(tmp, path)
        return path


@cache
def _code_digest() -> str:
    """A digest of the sources of ``wfbench`` and ``wfbench.policies``, the simulator and the teachers.

    A teacher's labels are a function of them: any change of either starts new cache files.
    """
    h = hashlib.sha256()
    for name in ("wfbench", "wfbench.policies"):
        spec = find_spec(name)
        for top in (spec and spec.submodule_search_locations) or []:
            for py in sorted(Path(top).rglob("*.py")):
                h.update(str(py.relative_to(top)).encode())
                h.update(py.read_bytes())
    return h.hexdigest()[:16]


class CachedTeacher(Teacher):
    """A :class:`Teacher` for an episode batch the teacher plays alone (``beta = 1``): labels from the cache.

    On a hit it replays the stored labels and never calls the policy; on a miss it asks the
    policy and stores the episode's labels once it is complete. Only valid while every
    environment follows the teacher: :class:`Trainer` uses it for those batches only.
    """

    def __init__(self, name: str, scenario, seeds: list[int], cache: LabelCache, horizon: int):
        self.name, self.scenario, self.seeds, self.cache, self.horizon = name, scenario, seeds, cache, horizon
        self.stored = cache.load(name, scenario, seeds)
        self.hit = self.stored is not None and len(self.stored) == horizon
        self.labels: list[dict[str, np.ndarray]] = []
        if not self.hit:
            super().__init__(teacher_policy(name), scenario, seeds)

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        t = int(np.asarray(obs["t"]).reshape(-1)[0])
        if self.hit:
            return {k: v.copy() for k, v in self.stored[t].items()}
        label = self.policy.act(obs)
        self.labels.append({k: np.array(v, copy=True) for k, v in label.items()})
        if len(self.labels) == self.horizon:
            self.cache.save(self.name, self.scenario, self.seeds, self.labels)
        return label


@dataclass
class DistillConfig(hindsight.HindsightConfig):
    """Every setting of a distillation run: hindsight learning's, with a deployable ``teacher``.

    The fields of :class:`~wfbench.train.hindsight.HindsightConfig` that serve its oracle (the
    value targets, the planner's settings) are not used, and refused if set.
    """

    model: str = "scalefree"
    teacher: str = DEFAULT_TEACHER  # a deployable policy of the registry (teacher_policy)
    run_dir: str = "runs/distill"
    # the schedule, per episode batch e: the first ``teacher_batches`` are the teacher's own play (beta = 1) on the
    # demonstration seeds, the same for every run seed, so their labels come from the cache after the first run;
    # then batch e follows the teacher with probability beta0 * beta_decay ** (e - teacher_batches + 1)
    teacher_batches: int = 8
    label_cache: str = ""  # folder of the teacher's cached labels; "" the default (LabelCache), "off": none
    beta_decay: float = 0.5
    # the mode whose public score picks best.pt: greedy, as the network that imitates a deterministic teacher is
    # deployed (sampling its calibrated uncertainty hires and lets go at random)
    select_mode: str = "greedy"

    def check(self) -> None:
        super().check()
        if self.model != scalefree.ARCH:
            raise ValueError(f"model {self.model!r} is not allowed for distill; allowed: {scalefree.ARCH} (the "
                             "network that reads every world's size, which distillation trains)")
        if self.select_mode not in SELECT_MODES:
            raise ValueError(f"select_mode {self.select_mode!r} is not allowed; allowed: {', '.join(SELECT_MODES)}")
        if type(self.teacher_batches) is not int or self.teacher_batches < 0:
            raise ValueError(f"teacher_batches = {self.teacher_batches!r} is not allowed; allowed: an integer >= 0")

    def check_teacher(self) -> None:
        """A deployable teacher, and none of the oracle's settings (checked first).

        One line on a teacher that is unknown, reads the future or decides less; the oracle's
        settings are refused here, before hindsight learning's own checks of them speak.
        """
        teacher_policy(self.teacher)
        for name, allowed in HINDSIGHT_ONLY.items():
            if getattr(self, name) != allowed:
                raise ValueError(f"{name} = {getattr(self, name)!r} is not allowed for distill; allowed: "
                                 f"{allowed!r} (it is a setting of hindsight learning's oracle)")

    def check_teacher_settings(self) -> None:
        """Nothing more: a deployable teacher has no planner settings (``check_teacher`` refused any)."""


DEMONSTRATION_SEED = 0  # the run seed whose window of training seeds the teacher's own play takes, for every run


class Trainer(hindsight.Trainer):
    """A distillation run: ``Trainer(config).train()``; ``resume=path`` continues a checkpoint (module docstring)."""

    ALGO = "distill"

    def __init__(self, config: DistillConfig, *args: Any, **kwargs: Any):
        self.labels = None if config.label_cache == "off" else LabelCache(config.label_cache or None)
        self.cache_stats = {"hits": 0, "misses": 0}
        super().__init__(config, *args, **kwargs)

    def demonstrating(self) -> bool:
        """Whether the next episode batch is the teacher's own play (the first ``teacher_batches``)."""
        return self.seed_cursor // self.run.config.num_envs < self.run.config.teacher_batches

    def episode_seeds(self) -> list[int]:
        """The demonstration seeds (the same for every run seed) while demonstrating, else the run's own."""
        if self.demonstrating():
            from wfbench.train.collection import take_seeds

            return take_seeds(DEMONSTRATION_SEED, self.seed_cursor, self.run.config.num_envs)
        return super().episode_seeds()

    def beta(self, iteration: int | None = None) -> float:
        """The probability that an environment follows the teacher in the iteration about to start (the schedule).

        That of the episode batch in progress, or of the next one where none is (a new run, a
        resumed one, or a batch that ended with the last iteration): what the iteration's first
        step mixes with, and what its history line records.
        """
        batch = self.seed_cursor // self.run.config.num_envs
        if self.sim is not None and not self.sim.done:
            batch -= 1  # _new_episode has moved the cursor past the batch in progress
        return self.batch_beta(batch)

    def batch_beta(self, batch: int) -> float:
        c = self.run.config
        return 1.0 if batch < c.teacher_batches else c.beta0 * c.beta_decay ** (batch - c.teacher_batches + 1)

    def mix_beta(self, beta: float) -> float:
        """The schedule's probability for the batch being played (a new one may start within an iteration)."""
        return self.beta()

    def teacher(self, scenario, seeds: list[int]):
        """The teacher of a new episode batch: replayed from the cache while it demonstrates, else the policy."""
        name = self.run.config.teacher
        if self.labels is not None and self.beta() >= 1.0:  # the new batch (_new_episode has made its simulator)
            teacher = CachedTeacher(name, scenario, seeds, self.labels, scenario.horizon)
            self.cache_stats["hits" if teacher.hit else "misses"] += 1
            return teacher
        return Teacher(teacher_policy(name), scenario, seeds)

    def evaluate_public(self) -> dict:
        """The public score that picks ``best.pt``, in ``select_mode`` (greedy by default)."""
        t0 = time.perf_counter()
        res = score_public(self.policy, self.run.scenario, self.run.config.eval_seeds, self.run.config.select_mode)
        self.timing["evaluate"] += time.perf_counter() - t0
        return res

    @torch.no_grad()
    def agreement(self, scenario=None, seeds: str = "public:2", steps: int | None = None) -> dict[str, float]:
        """How often the network's greedy action is the teacher's, on the teacher's own play of public seeds.

        States no training batch visits (the public seeds select, the training seeds train):
        the teacher plays ``steps`` steps (default the whole horizon) of ``scenario`` (default
        the run's, its first world across worlds), and at each step the network, fed the same
        observations, acts greedily. Returns the share of agreeing decisions (dispatch over the
        facilities that choose, workforce over the environments) and ``nll_HEAD``, the mean
        negative log-likelihood of the teacher's labels per environment and step for each of
        the three heads (the imitation loss on these states; positioning, which acts only
        when a move is due, is measured by it alone).
        """
        from wfbench.core.seeds import resolve_seeds
        from wfbench.core.simulator import Simulator
        from wfbench.train.collection import policy_step

        scenario = scenario or self.run.scenario
        if isinstance(scenario, WorldSet):
            scenario = scenario.worlds[0].config
        seed_list = resolve_seeds(seeds)
        sim = Simulator(scenario, seed_list, keep_series=False, threads=1)
        obs = sim.reset()
        teacher = Teacher(teacher_policy(self.run.config.teacher), scenario, seed_list)
        dev = self.run.device
        state = self.model.initial_state(sim.B, dev)
        starts = torch.ones(sim.B, device=dev)
        self.model.eval()
        hits = {"dispatch": 0, "workforce": 0}
        counts = {"dispatch": 0, "workforce": 0}
        nll = {k: 0.0 for k in hindsight.HEADS}
        for _ in range(min(steps or scenario.horizon, scenario.horizon)):
            _, x, out, state, acts = policy_step(self.model, obs, state, starts, self.model, None, self.run.amp)
            mine = {k: v.cpu().numpy() for k, v in acts.items()}
            label = teacher.act(obs)
            ld, lw, lp, _ = hindsight.oracle_labels(label, obs)
            labels = {k: torch.as_tensor(v, device=dev) for k, v in zip(hindsight.HEADS, (ld, lw, lp), strict=True)}
            for k, v in hindsight.scalefree_label_log_probs(self.model, out, x, labels).items():
                nll[k] -= float(v.sum())
            choosing = x["choose"].cpu().numpy()
            hits["dispatch"] += int((mine["dispatch"] == ld)[choosing].sum())
            counts["dispatch"] += int(choosing.sum())
            hits["workforce"] += int((mine["workforce"] == lw).sum())
            counts["workforce"] += lw.size
            obs = sim.step_observe(label)[1]
            starts = torch.zeros(sim.B, device=dev)
            if sim.done:
                break
        return {**{k: hits[k] / max(counts[k], 1) for k in ("dispatch", "workforce")},
                **{f"nll_{k}": nll[k] / max(counts["workforce"], 1) for k in hindsight.HEADS}}


__all__ = ["DEFAULT_TEACHER", "CachedTeacher", "DistillConfig", "LabelCache", "Teacher", "Trainer",
           "teacher_policy"]
