"""Training: PPO for the paper's joint model (:mod:`wfbench.train.ppo`); imports torch.

An application-layer package beside ``wfbench.evaluation``: it drives the Simulator and
the network of :mod:`policies.neural`. ``import wfbench`` never imports it.
"""
