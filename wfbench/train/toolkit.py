"""What the trainers (ppo, impala, hindsight) share, under one name: the parts re-exported as they were.

Each job has its own module: :mod:`~wfbench.train.config` (the settings),
:mod:`~wfbench.train.precision` (autocast), :mod:`~wfbench.train.collection` (acting: the
``Collector``), :mod:`~wfbench.train.record` (the ``Run`` and its start),
:mod:`~wfbench.train.checkpoints`, :mod:`~wfbench.train.scoring` (the public score that
selects checkpoints) and :mod:`~wfbench.train.outputs` (``RunOutputs``). ``toolkit.NAME``
stays for code written against it (``hindsight.py`` and user scripts); new code imports
NAME from its module (``docs/design.md``, "Training").
"""

from wfbench.train.checkpoints import (
    init_weights,
    load_run,
    run_checkpoint,
    save_atomic,
    save_run,
    save_unselected_best,
)
from wfbench.train.collection import Collector, RunningStd, episode_kpis, policy_step, take_seeds
from wfbench.train.config import (
    DECISIONS,
    DEVICES,
    ActorCriticConfig,
    BaseConfig,
    build_model,
    check_ints,
    check_numbers,
    network_config,
)
from wfbench.train.outputs import RunOutputs
from wfbench.train.precision import AMP_DTYPES, amp_dtype, autocast
from wfbench.train.record import Run, git_commit, start_run, torch_device, write_run_config
from wfbench.train.scoring import SELECT_MODES, deployable, log_public, score_public, score_worlds

__all__ = [
    "AMP_DTYPES", "ActorCriticConfig", "BaseConfig", "Collector", "DECISIONS", "DEVICES", "Run", "RunOutputs",
    "RunningStd", "SELECT_MODES", "amp_dtype", "autocast", "build_model", "check_ints", "check_numbers", "deployable",
    "episode_kpis", "git_commit", "init_weights", "load_run", "log_public", "network_config", "policy_step",
    "run_checkpoint", "save_atomic", "save_run", "save_unselected_best", "score_public", "score_worlds", "start_run",
    "take_seeds", "torch_device", "write_run_config",
]
