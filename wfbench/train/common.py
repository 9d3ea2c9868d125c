"""What the trainers (ppo, impala, hindsight) share, so a change to one of these cannot break the others.

The checkpoint format, scoring on the public seeds, the run files, the outputs of a
training loop (:class:`RunOutputs`: TensorBoard, progress bar, ``best.pt``, checkpoints,
the save on Ctrl-C), the return normalizer, the deployable policy of a network, the
device and the git commit.
A checkpoint of any trainer loads as a policy (``ppo:PATH``, :mod:`policies.neural.policy`)
because all three write the keys of :func:`policy_checkpoint`; each adds what its own
resume needs. Checkpoints are selected on the public seeds only (:func:`score_public`).
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

import policies
from policies.neural.model import count_parameters
from policies.neural.policy import PPOPolicy
from wfbench.core.seeds import resolve_seeds
from wfbench.evaluation import evaluate


def score_public(policy: Callable[[str], Any], scenario, eval_seeds: str) -> dict:
    """Mean NSW and workforce cost on the public selection seeds, sampled and greedy (the score is the sampled one).

    ``policy(mode)`` gives the deployable policy in ``mode`` (``"sample"`` or ``"greedy"``).
    """
    seeds = resolve_seeds(eval_seeds)
    res: dict = {}
    for mode in ("sample", "greedy"):
        df = evaluate(policy(mode), scenario, seeds, backend="serial", act_timeout_s=None)
        res[mode] = float(df["nsw"].mean())
        res[f"{mode}_workforce_cost"] = float(df["workforce_cost"].mean())
    res["seeds"] = seeds
    return res


def log_public(writer, res: dict, step: int) -> None:
    """The TensorBoard scalars of a :func:`score_public` result (``public/*``)."""
    writer.add_scalar("public/nsw_sample", res["sample"], step)
    writer.add_scalar("public/nsw_greedy", res["greedy"], step)
    writer.add_scalar("public/workforce_cost_sample", res["sample_workforce_cost"], step)


class RunOutputs:
    """What the three trainers' loops write besides learning: the loop's scaffolding in one place.

    ``with RunOutputs(trainer, unit, desc, total, initial) as out:`` opens the TensorBoard
    writer (``RUN/tb``, when ``trainer.log``) and the progress bar (when ``trainer.progress``;
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
        if trainer.log:
            from torch.utils.tensorboard import SummaryWriter

            self.writer = SummaryWriter(str(trainer.run_dir / "tb"))
        if trainer.progress:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="step", unit_scale=True, desc=desc)

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        t = self.trainer
        latest = t.run_dir / "latest.pt"
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
                self.writer.add_scalar(f"{prefix}/{k}", values[k], self.trainer.global_step)

    def episodes(self, episodes: list[dict]) -> None:
        """The finished training episodes' KPIs (``episode/*``)."""
        for ep in episodes:
            self.scalars("episode", ep)
            self.last_nsw = ep["nsw"]

    def public(self, res: dict, count: int) -> None:
        """Log a :func:`score_public` result; keep ``best.pt`` (the policy only) when its sampled score is the best."""
        t = self.trainer
        if self.writer:
            log_public(self.writer, res, t.global_step)
        if res["sample"] > t.best["score"]:
            t.best = {"score": res["sample"], "update": count, "global_step": t.global_step, "mode": "sample",
                      "seeds": res["seeds"], "greedy": res["greedy"]}
            t.save(t.run_dir / "best.pt", full=False)

    def checkpoint(self, name: str) -> None:
        """``checkpoints/NAME`` and ``latest.pt``, both resumable."""
        self.trainer.save(self.trainer.run_dir / "checkpoints" / name)
        self.trainer.save(self.trainer.run_dir / "latest.pt")

    def advance(self, steps: int, postfix: dict) -> None:
        """Move the progress bar by ``steps``; ``postfix``, the last training episode's NSW, the best public score."""
        if self.bar:
            self.bar.update(steps)
            postfix = dict(postfix)
            if self.last_nsw is not None:
                postfix["ep_nsw"] = f"{self.last_nsw:.3f}"
            if self.trainer.best["update"] is not None:
                postfix["public"] = f"{self.trainer.best['score']:.3f}"
            self.bar.set_postfix(postfix)


def policy_checkpoint(model: torch.nn.Module, model_config, variant: str, scenario: str, train_config,
                      **fields) -> dict:
    """The keys every checkpoint has (what ``ppo:PATH`` loads), plus the trainer's counters in ``fields``."""
    return {
        "model": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "model_config": model_config.to_dict(),
        "variant": variant,
        "scenario": scenario,
        "train_config": asdict(train_config),
        **fields,
    }


def save_atomic(ckpt: dict, path: Path) -> Path:
    """``torch.save`` through a temporary file, so a crash never leaves half a checkpoint at ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    torch.save(ckpt, tmp)
    tmp.replace(path)
    return path


def write_run_config(run_dir: Path, train_config, model: torch.nn.Module, model_config, device, commit: str,
                     **extra) -> None:
    """``RUN/config.json``: every setting, the git commit, the parameter count, the device and the network's sizes."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "config.json").write_text(json.dumps(
        {**asdict(train_config), **extra, "git_commit": commit, "parameters": count_parameters(model),
         "device": str(device), "model_config": model_config.to_dict()}, indent=2))


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
    net = PPOPolicy(copy.deepcopy(model).float().cpu(), mode=mode, device="cpu", name=name)
    if variant == "joint":
        return net
    return policies.Composite(net, "threshold", "spatial", name=name)
