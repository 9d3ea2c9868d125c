"""Training: one module per algorithm (ppo, impala, hindsight) on one toolkit (:mod:`wfbench.train.toolkit`).

The algorithms are listed by name in :mod:`wfbench.train.registry`, which imports no
torch (the other modules do). An application-layer package beside ``wfbench.harness.evaluation``:
it drives the Simulator and the network of :mod:`wfbench.policies.neural`. ``import wfbench``
never imports it.
"""
