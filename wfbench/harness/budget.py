"""What a result cost: the machine it ran on, and what the policy cost before it ran.

Every evaluation row carries :data:`BUDGET_COLUMNS` (``decision_ms_p50``, ``decision_ms_p99``,
``cpu_s``), taken by :func:`wfbench.harness.runner.run_batch` where the chunk ran; numba's loading
and compiling is left out. They are measurements, not results, and never part of a comparison
of results (:func:`results_only`). :func:`machine` describes where a chunk ran;
:func:`policy_budget` what the policy states about its own cost (training steps and hardware,
tuning trials, a solver's time limit). How each policy family is timed: ``docs/leaderboard.md``,
"What a result cost".
"""

from __future__ import annotations

import functools
import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

import pandas as pd

BUDGET_COLUMNS = ("decision_ms_p50", "decision_ms_p99", "cpu_s")
NOT_RECORDED = "not recorded"


def results_only(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` without the budget columns: what two runs of the same seeds must agree on to the bit."""
    return df.drop(columns=[c for c in BUDGET_COLUMNS if c in df.columns])


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return " ".join(line.partition(":")[2].split())
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


@functools.lru_cache(maxsize=1)
def machine() -> dict[str, Any]:
    """This machine: platform, CPU model, core count and the versions of Python, numpy, numba and torch.

    Versions come from the installed packages' metadata, so torch is not imported.
    """
    return {
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "cores": os.cpu_count() or 1,
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "numba": _version("numba"),
        "torch": _version("torch"),
    }


def machine_line(m: dict[str, Any]) -> str:
    """One line for a table: ``CPU, N cores, OS arch, py X, numba Y`` (and the backend and workers when given)."""
    system = m.get("platform", "").split("-")
    os_arch = " ".join(x for x in (system[0] if system else "", platform_machine(m)) if x)
    text = f"{m.get('cpu', '?')}, {m.get('cores', '?')} cores, {os_arch}, py {m.get('python', '?')}, " \
           f"numba {m.get('numba', '?')}"
    if m.get("backend"):
        text += f"; {m['backend']}" + (f" x{m['workers']}" if m.get("workers") else "")
    return text


def platform_machine(m: dict[str, Any]) -> str:
    """The architecture in a :func:`machine` record's platform string (``x86_64``, ``arm64``), or ``""``."""
    for arch in ("x86_64", "aarch64", "arm64", "AMD64", "i686"):
        if arch in m.get("platform", ""):
            return arch
    return ""


def training_hardware(device: Any = None) -> str:
    """A trainer's hardware in one line: the CPU and core count, and the GPU when ``device`` is a CUDA device."""
    m = machine()
    text = f"{m['cpu']}, {m['cores']} cores"
    if device is not None and getattr(device, "type", str(device)) == "cuda":
        import torch  # a CUDA device: torch is loaded already

        text += f", GPU {torch.cuda.get_device_name(device)}"
    return text


# -- what a policy states about its own cost --------------------------------------------------------------------
def policy_budget(spec: Any, policy: Any = None) -> dict[str, Any]:
    """What ``spec`` (and the loaded ``policy``, when given) states about its cost.

    - a network (``ALGO:PATH`` or a shipped name): ``train_env_steps`` (the checkpoint's
      ``global_step``), ``train_wall_s`` and ``train_hardware`` (``"not recorded"`` for a
      checkpoint written before wfbench saved them), and ``init`` when it started from
      another checkpoint's weights;
    - a tuned file (a path or a shipped name): ``trials`` of its search and the ``tuned_on`` scenario;
    - a policy with solver-backed decisions: ``solver_time_limit_s``, each such decision's
      limit per solve (``{decision: seconds}``);
    - anything else: ``kind`` only.

    Returns:
        A JSON-serializable dict with at least ``kind``.
    """
    from wfbench.policies import registry, tuned

    out: dict[str, Any] = {"kind": "other"}
    if isinstance(spec, str):
        p = registry.parse_spec(spec)  # the registry's one reading of the spec
        if p.kind in ("learned", "checkpoint"):
            out = {"kind": "learned", **_checkpoint_budget(Path(p.path))}
        elif p.kind in ("tuned", "tuned-file"):
            t = tuned.read(Path(p.path))
            out = {"kind": "tuned", "trials": int(t.trials), "tuned_on": t.scenario}
        elif p.kind != "entry-point":
            out = {"kind": "builtin"}
    limits = solver_time_limits(policy)
    if limits:
        out["solver_time_limit_s"] = limits
    return out


def _checkpoint_budget(path: Path) -> dict[str, Any]:
    from wfbench.policies.neural.policy import load_checkpoint  # imports torch: only for a network

    ckpt = load_checkpoint(path)
    out: dict[str, Any] = {
        "train_env_steps": int(ckpt.get("global_step", 0)),
        "train_wall_s": float(ckpt["train_wall_s"]) if "train_wall_s" in ckpt else NOT_RECORDED,
        "train_hardware": str(ckpt.get("train_hardware") or NOT_RECORDED),
    }
    init = (ckpt.get("train_config") or {}).get("init")
    if init:
        out["init"] = Path(str(init)).name  # the file it started from, not the trainer's path
    return out


def solver_time_limits(policy: Any) -> dict[str, float]:
    """``{decision: seconds}`` for each part of ``policy`` that calls a solver with a time limit per solve."""
    if policy is None:
        return {}
    parts = getattr(policy, "parts", None)
    items = parts.items() if isinstance(parts, dict) else [(d, policy) for d in getattr(policy, "decisions", ())]
    return {d: float(p.time_limit_s) for d, p in items if getattr(p, "time_limit_s", None) is not None}


def budget_line(b: dict[str, Any]) -> str:
    """A :func:`policy_budget` record in a few words, for a table cell (``"-"`` when it states nothing)."""
    parts = []
    if b.get("kind") == "learned":
        steps = b.get("train_env_steps")
        parts.append(f"{steps:,} env-steps" if isinstance(steps, int) else f"env-steps {NOT_RECORDED}")
        wall = b.get("train_wall_s", NOT_RECORDED)
        parts.append(f"wall {wall / 3600:.2f} h" if isinstance(wall, int | float) else f"wall {wall}")
        parts.append(f"hardware {b.get('train_hardware', NOT_RECORDED)}")
        if b.get("init"):
            parts.append(f"from {b['init']}")
    elif b.get("kind") == "tuned":
        parts.append(f"{b.get('trials')} trials on {b.get('tuned_on')}")
    limits = b.get("solver_time_limit_s") or {}
    if limits:
        parts.append("solver limit " + ", ".join(f"{d} {s:g} s" for d, s in limits.items()))
    return "; ".join(parts) or "-"

