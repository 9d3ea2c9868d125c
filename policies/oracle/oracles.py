"""The hindsight oracles as policies: one part per decision, sharing one planner inside a composite.

:class:`OracleDispatch`, :class:`OracleWorkforce` and :class:`OraclePositioning` are the
per-decision ``oracle`` of :data:`wfbench.policies.decisions.DECISIONS`. Each holds a
:class:`~wfbench.policies.oracle.planner.Planner`; :class:`policies.Composite` calls
:meth:`join` on its trace-reading parts, so they share one planner that decides them together
and models the composite's built-in parts exactly. They read the future (``reads_trace = True``,
``attach(config)`` before ``reset(seeds)``): not deployable (``docs/hindsight.md``,
"Composites and how to run them").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.oracle.planner import Planner

from wfbench.core.config import ScenarioConfig


class _OraclePart:
    """One decision of a hindsight planner, as a policy."""

    decision = ""
    reads_trace = True

    def __init__(self, **settings: int):
        self.settings = settings
        self.planner = Planner((self.decision,), **settings)
        self.decisions = (self.decision,)
        self.name = "oracle"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.planner.decide})"

    def join(self, parts: dict[str, Any]) -> None:
        """Share one planner with the other oracle parts of a composite; model its built-in parts exactly.

        ``parts`` maps each decision to the composite's part for it.
        """
        mine = {d: p for d, p in parts.items() if isinstance(p, _OraclePart)}
        planners = {id(p.planner) for p in mine.values()}
        if len(planners) == 1 and set(next(iter(mine.values())).planner.decide) == set(mine):
            planner = next(iter(mine.values())).planner
        else:
            planner = Planner(tuple(mine), **self.planner.settings())
        for d, part in parts.items():
            if d not in mine and isinstance(part, BuiltinDecision):
                planner.use_part(d, part.code, part.hp, part.seed)
        for part in mine.values():
            part.planner = planner

    def attach(self, config: ScenarioConfig) -> None:
        self.planner.attach(config)

    def reset(self, seeds: int | Sequence[int]) -> None:
        self.planner.reset(seeds)

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {self.decision: self.planner.act(obs)[self.decision]}

    def record(self, actions: dict[str, np.ndarray]) -> None:
        self.planner.record(actions)


class OracleDispatch(_OraclePart):
    """Dispatch by exact look-ahead over candidate assignments (``docs/hindsight.md``)."""

    decision = "dispatch"


class OracleWorkforce(_OraclePart):
    """Hire and let go by exact look-ahead over the seven workforce actions (``docs/hindsight.md``)."""

    decision = "workforce"


class OraclePositioning(_OraclePart):
    """Hire at the p-median of the known future demand, let go the cheapest loss (``docs/hindsight.md``)."""

    decision = "positioning"
