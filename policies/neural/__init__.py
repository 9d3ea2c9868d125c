"""Learned policies: the paper's joint network (torch), its action distributions and checkpoints as policies.

Importing this package imports torch; ``import policies`` does not import it, and
``policies.get("ppo:path/to/ckpt.pt")`` imports it on first use. ``docs/rl.md`` has the
model, the trainer (``wfbench.train.ppo``) and the shipped checkpoints
(``policies/neural/checkpoints/``).
"""
