"""Tuning, the OR sibling of :mod:`wfbench.train`: a policy's parameters searched on public seeds.

:func:`tune` runs Optuna's TPE over a policy's declared search space (:data:`wfbench.policies.rules.RULES`) on one
scenario or across a suite's training worlds, and writes a tuned file that every command loads by name.
"""

from wfbench.tune.search import (
    OBJECTIVE_WORLDS,
    TuneResult,
    TuningWorld,
    check_tuning_seeds,
    search_space,
    tune,
    tuning_worlds,
)

__all__ = ["OBJECTIVE_WORLDS", "TuneResult", "TuningWorld", "check_tuning_seeds", "search_space", "tune",
           "tuning_worlds"]
