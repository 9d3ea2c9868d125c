"""The policy protocol and the helpers every policy family shares.

A policy has ``decisions`` (the agents it acts for), ``reset(seeds)`` (one seed per
environment of the batch it will see) and ``act(obs) -> {agent: batched action}`` for
those agents. The evaluator never asks what kind of policy it holds. ``docs/policies.md``
lists every observation key and action; :mod:`wfbench.policies.composite` combines one policy
per decision.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from wfbench.policies import kernels as K

from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.observe import Obs
from wfbench.core.rng import key_from_seed

DECISION_INDEX = {"dispatch": 0, "workforce": 1, "positioning": 2}


@runtime_checkable
class Policy(Protocol):
    """What the evaluator needs of a policy."""

    decisions: tuple[str, ...]

    def reset(self, seeds: Sequence[int]) -> None: ...

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]: ...


class Attached:
    """``attach``, which wfbench's runner calls before ``reset`` on a policy that reads the trace, and its check.

    The hindsight oracles and their planner mix it in; they set ``config = None`` in their
    ``__init__`` and take the scenario from :meth:`_attached` in ``reset``.
    """

    config: ScenarioConfig | None = None

    def attach(self, config: ScenarioConfig) -> None:
        """Tell it the scenario (the runner does, before ``reset``, for policies that read the trace)."""
        self.config = require_config(config, f"{type(self).__name__}.attach")

    def _attached(self) -> ScenarioConfig:
        """The scenario ``attach`` gave; RuntimeError of one line saying the order of the calls otherwise."""
        if self.config is None:
            raise RuntimeError("a hindsight oracle needs the scenario: call attach(config) before reset(seeds) "
                               "(wfbench's runner does this for policies with reads_trace = True)")
        return self.config


def decision_key(env_seed: int, policy_seed: int, decision: str) -> np.uint64:
    """The random key of one decision of a policy in the environment with ``env_seed``.

    Keyed by the environment's seed, never by its batch position, so a seed decides the
    same alone or inside any batch.
    """
    return key_from_seed(int(env_seed), int(policy_seed), 0xB01 + DECISION_INDEX[decision])


def as_obs(obs: dict[str, np.ndarray]) -> Obs:
    return Obs(**{name: obs[name] for name in Obs._fields})


def seeds_array(seeds: int | Sequence[int]) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(seeds, dtype=np.int64))
    if arr.ndim != 1 or (arr < 0).any():
        raise ValueError(f"seeds must be integers >= 0, one per environment; got {seeds!r}")
    return arr


def hp_vector(hp: dict[str, float], name: str) -> np.ndarray:
    """The hyper-parameter vector (``wfbench.policies.kernels.HP_FIELDS`` order) with ``hp`` over the defaults."""
    unknown = set(hp) - set(K.HP_FIELDS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for {name}; allowed: {list(K.HP_FIELDS)}")
    params = dict(K.HP_DEFAULTS, **hp)
    return np.array([float(params[f]) for f in K.HP_FIELDS])
