"""Deployable lookahead policies (issue #43): they plan on worlds sampled from what they observe.

- :mod:`wfbench.policies.lookahead.rollout`: rollout of a compiled base policy on K sampled
  futures of H steps (:class:`Rollout`), with budget presets (:data:`BUDGETS`).
- :mod:`wfbench.policies.lookahead.mpc`: a rolling-horizon staffing MILP on a forecast
  (:class:`MPC`: ``mpc-rates`` on the public rates, ``mpc-ma`` on a moving average).

The worlds come from :class:`wfbench.core.belief.Belief`: they agree with every observation
and draw the unobserved from the public model under the policy's own keys. The oracles
that read the true future are :mod:`wfbench.policies.oracle`.
"""

from wfbench.policies.lookahead.mpc import MPC
from wfbench.policies.lookahead.rollout import BUDGETS, DEFAULT_BUDGET, Rollout, budget, knob, make

__all__ = ["BUDGETS", "DEFAULT_BUDGET", "MPC", "Rollout", "budget", "knob", "make"]
