"""Training: one module per algorithm (ppo, impala, hindsight) on what they share (config, collection, record, ...).

:func:`fit` trains a run from its settings, as ``wfbench train`` does (:mod:`wfbench.train.runs`).
The algorithms are listed by name in :mod:`wfbench.train.registry`, which imports no
torch (the other modules do; :mod:`wfbench.train.runs` only once :func:`fit` runs). An
application-layer package beside ``wfbench.harness.evaluation``: it drives the Simulator
and the network of :mod:`wfbench.policies.neural`. ``import wfbench`` never imports it.
"""

from wfbench.train.runs import RESUME_MAY_CHANGE, SettingsError, fit

__all__ = ["RESUME_MAY_CHANGE", "SettingsError", "fit"]
