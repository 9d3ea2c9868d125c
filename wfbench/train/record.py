"""The record of a training run (:class:`Run`), its start (:func:`start_run`) and its ``config.json``.

Every trainer holds a :class:`Run` as ``run``: its config, device, scenario, folder, progress,
provenance and cost (``docs/rl.md``, "The trainers").
"""

from __future__ import annotations

import json
import math
import subprocess
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch

from wfbench.core.config import ScenarioConfig
from wfbench.harness.budget import training_hardware
from wfbench.policies.neural.model import count_parameters
from wfbench.train.config import BaseConfig
from wfbench.train.memory import keep_freed_memory
from wfbench.train.precision import amp_dtype
from wfbench.train.worlds import WorldSet


@dataclass
class Run:
    """The record of a training run that every trainer holds as ``run`` (:func:`start_run` makes it).

    Fixed at the start: ``config``, ``device``, ``scenario`` (a ScenarioConfig, or a
    WorldSet across worlds), ``network`` (the network's config), ``dir`` (the run folder),
    ``progress`` and ``log`` (progress bar, TensorBoard). The run's progress, saved in every
    checkpoint and restored by :func:`wfbench.train.checkpoints.load_run`: ``global_step``
    (environment steps), ``best`` (the best public score and where it was reached,
    :meth:`wfbench.train.outputs.RunOutputs.public`) and ``history`` (the public scores).
    Its provenance and cost: ``commit`` (the code the run started from; a resumed run keeps
    its first), ``hardware`` (of each segment),
    ``wall_before`` (seconds of the earlier segments of a resumed run; None when its
    checkpoint did not record them) and ``wall_start`` (``time.monotonic()`` when this
    segment started). ``amp``: the autocast dtype of its forward passes (None: float32;
    :func:`amp_dtype`).
    """

    config: BaseConfig
    device: torch.device
    scenario: ScenarioConfig | WorldSet
    network: Any
    dir: Path
    progress: bool
    log: bool
    commit: str
    hardware: str
    wall_before: float | None = 0.0
    wall_start: float = field(default_factory=time.monotonic)
    best: dict = field(default_factory=lambda: {"score": -math.inf, "update": None})
    history: list = field(default_factory=list)
    global_step: int = 0
    amp: torch.dtype | None = None

    @property
    def cuda(self) -> bool:
        """Whether the run is on a CUDA device."""
        return self.device.type == "cuda"


def start_run(config: BaseConfig, progress: bool, log: bool, amp: str | torch.dtype | None = "auto") -> Run:
    """Check ``config``, set torch's threads and seed; the :class:`Run` record of a fresh run on it.

    On CPU, the process keeps freed memory for reuse (:func:`wfbench.train.memory.keep_freed_memory`:
    the speed of an update, not its bits).

    ``amp``: the autocast dtype of the run's forward passes (:func:`amp_dtype`; ``"auto"``:
    bfloat16 on CUDA with ``config.bf16``, float32 on CPU).
    """
    # resolved once, by the check; several worlds (``scenarios``): a WorldSet, which the collector, the public
    # scores and the checkpoint read
    scenario = config.validate()
    device = torch_device(config.device)
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    if device.type == "cpu":
        keep_freed_memory()
    return Run(config=config, device=device, scenario=scenario, network=config.network_config(),
               dir=Path(config.run_dir), progress=progress, log=log, commit=git_commit(),
               hardware=training_hardware(device), amp=amp_dtype(device, config.bf16, amp))


def torch_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10,
                             cwd=Path(__file__).resolve().parent)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, timeout=10, cwd=Path(__file__).resolve().parent).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "") if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def write_run_config(run: Run, model: torch.nn.Module, **extra) -> None:
    """``RUN/config.json``: every setting, the git commit, the parameter count, the device and the network's sizes."""
    run.dir.mkdir(parents=True, exist_ok=True)
    (run.dir / "config.json").write_text(json.dumps(
        {**asdict(run.config), **extra, "git_commit": run.commit, "parameters": count_parameters(model),
         "device": str(run.device), "model_config": run.network.to_dict()}, indent=2))
