"""Hindsight oracles: planners that see the episode's whole exogenous future and decide with it.

Not deployable: they show how much a deployable policy leaves on the table, and can
teach one later. Modules: ``dispatch``, ``workforce`` and ``positioning`` (each
decision's candidates and maps), ``planner`` (the shadow simulator, forks and scoring),
``oracles`` (the per-decision policies), ``best`` (the registry's ``oracle``: per seed,
the best in hindsight of the planner and every deployable built-in), ``references`` (the
versioned candidate lists: ``oracle`` is v1, ``oracle-v2`` is v2), ``hindsight``
(``oracle-rollout``), ``replay``, ``episodes`` and ``pieces`` (the replaying references'
totals from recorded episodes and committed suite pieces). ``docs/hindsight.md``
explains them; the look-ahead itself is :mod:`wfbench.core.fork`, rolled forward by
:mod:`wfbench.policies.kernels.forward`.
"""

from wfbench.policies.oracle.best import BestInHindsight
from wfbench.policies.oracle.oracles import OracleDispatch, OraclePositioning, OracleWorkforce
from wfbench.policies.oracle.planner import Planner, ShadowDivergedError

__all__ = ["BestInHindsight", "OracleDispatch", "OraclePositioning", "OracleWorkforce", "Planner",
           "ShadowDivergedError"]
