"""A trainer's checkpoints: the keys every one has, saving, resuming and starting from another's weights.

A checkpoint of any trainer loads as a policy by its algorithm (``impala:PATH``,
``hindsight:PATH``, ``ppo:PATH``; ``ppo:`` loads any, :mod:`wfbench.policies.registry`)
because all three write the keys of :func:`run_checkpoint`; each adds what its own resume
needs (:func:`save_run`, :func:`load_run`). Files are written whole (:func:`save_atomic`).
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from wfbench.policies.neural.policy import load_checkpoint
from wfbench.train.worlds import WorldSet


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
