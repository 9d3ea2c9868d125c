"""The second training process started ahead: its imports overlap the first process's (no torch here).

A two-process PPO run (:mod:`wfbench.train.shards`) starts its second process when the
trainer is built, after the first process has imported torch and the trainer; the second
then imports them too (about 3 s of the 2-core VM) before it builds its own trainer, and
the first waits for it. ``wfbench train`` calls :func:`start` before its own imports when
the run will likely have two processes: the process starts at once and imports
``preload`` meanwhile, then waits on its stdin for the key that :class:`~wfbench.train.shards.Worker`
sends when it :func:`take` s it. A standby that no trainer takes is let go by :func:`release`
(at exit too): its stdin closes and it ends. docs/performance.md, "Training across the training split".
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys

# shards = 0 (auto): 2 from this batch on; below, two processes gain nothing (docs/performance.md). Here, with no
# torch import, so that wfbench train's guess reads the same number as the trainer
AUTO_SHARD_ENVS = 64

_standby: subprocess.Popen | None = None


def usable_cores() -> int:
    """The CPU cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def start(preload: str) -> None:
    """Start the standby process (once), importing module ``preload`` while it waits for its work."""
    global _standby
    if _standby is not None:
        return
    _standby = subprocess.Popen([sys.executable, "-m", "wfbench.train.shards", "--preload", preload],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    atexit.register(release)


def take() -> subprocess.Popen | None:
    """The standby process, for a :class:`~wfbench.train.shards.Worker` to use (None: none, or it is gone)."""
    global _standby
    proc, _standby = _standby, None
    return proc if proc is not None and proc.poll() is None else None


def release() -> subprocess.Popen | None:
    """Let the standby go, if no trainer took it: its stdin closes and it ends on its own; returns it (None: none)."""
    proc = take()
    if proc is not None:
        proc.stdin.close()
        proc.stdout.close()
    return proc
