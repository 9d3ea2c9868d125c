"""Learned policies: the paper's joint network (torch), its action distributions and checkpoints as policies.

Importing this package imports no torch (its modules do); ``import policies`` does not
import it, and ``policies.get("ppo:path/to/ckpt.pt")`` imports it on first use.
``docs/rl.md`` has the model and the trainers (``wfbench.train``, one module per
algorithm), and the shipped checkpoints (``policies/neural/checkpoints/``).
"""

# the algorithms a checkpoint can name in its ``algo`` key, each its prefix ``ALGO:PATH``
# (wfbench.train.registry.ALGORITHMS; tests/train/test_train_registry.py checks the two agree)
CHECKPOINT_ALGORITHMS = ("ppo", "impala", "hindsight", "distill")
ALIAS = "ppo"  # the prefix that loads a checkpoint of any algorithm (the one every checkpoint loaded by before)
