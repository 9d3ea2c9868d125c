"""What the trainers (ppo, impala, hindsight) share, so a change to one of these cannot break the others.

The checkpoint format, scoring on the public seeds, the run files, the return
normalizer, the deployable policy of a network, the device and the git commit.
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
from wfbench.evaluation import evaluate
from wfbench.seeds import resolve_seeds


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
