"""The training algorithms by name: what ``wfbench train --algo`` offers and how a checkpoint names its trainer.

Importing this module imports no torch: the command line reads :data:`ALGORITHMS` for
``--algo`` and its help. A new algorithm is one module under ``wfbench/train/`` with a
config dataclass (built on :class:`wfbench.train.config.BaseConfig`) and a ``Trainer``
class, plus one row here and its name in :data:`wfbench.policies.neural.CHECKPOINT_ALGORITHMS` (the
policy layer cannot import this one; ``tests/train/test_train_registry.py`` checks the two agree).
Every checkpoint records its algorithm (``algo``) and loads as the policy ``NAME:PATH``;
``ppo:PATH`` loads any (the alias kept from before the others had their own prefix).
"""

from __future__ import annotations

import importlib
from typing import NamedTuple


class Algorithm(NamedTuple):
    """One training algorithm: its module under ``wfbench.train`` and the names in it."""

    name: str  # --algo NAME, and the ``algo`` key of every checkpoint it writes
    module: str  # the module that holds the config class and the Trainer
    config: str  # the name of its config dataclass in that module
    summary: str  # one line for --help and the docs

    def load(self):
        """The algorithm's module (imports torch)."""
        return importlib.import_module(self.module)

    def config_class(self) -> type:
        return getattr(self.load(), self.config)

    def trainer_class(self) -> type:
        return self.load().Trainer


ALGORITHMS: dict[str, Algorithm] = {
    "ppo": Algorithm("ppo", "wfbench.train.ppo", "TrainConfig",
                     "PPO with the paper's joint model (or dispatch-only, or one network per decision)"),
    "impala": Algorithm("impala", "wfbench.train.impala", "ImpalaConfig",
                        "IMPALA: an actor with lagging parameters, a learner with V-trace"),
    "hindsight": Algorithm("hindsight", "wfbench.train.hindsight", "HindsightConfig",
                           "hindsight learning: imitation of the oracles (DAgger) or the learner's own action values"),
    "distill": Algorithm("distill", "wfbench.train.distill", "DistillConfig",
                         "distillation: imitation of a deployable teacher that searches (a rollout, the network's "
                         "search) on the network's own states (DAgger)"),
}
DEFAULT_ALGORITHM = "ppo"


def get_algorithm(name: str) -> Algorithm:
    """The algorithm called ``name``; a ValueError lists those there are."""
    try:
        return ALGORITHMS[name]
    except KeyError:
        raise ValueError(f"algorithm {name!r} is not known; allowed: {', '.join(ALGORITHMS)}") from None
