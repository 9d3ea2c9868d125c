"""Deployable lookahead policies (issue #43): they plan on worlds sampled from what they observe.

:mod:`~wfbench.policies.lookahead.rollout` rolls a compiled base policy forward on K sampled
futures (:class:`Rollout`, :data:`BUDGETS`); :mod:`~wfbench.policies.lookahead.network_rollout`
does it with a trained network as the base (:class:`NetworkRollout`);
:mod:`~wfbench.policies.lookahead.search` searches with the network, greedy futures ended at its
value and a noise test (:class:`NetworkSearch`);
:mod:`~wfbench.policies.lookahead.mpc` solves a rolling-horizon staffing MILP on a forecast
(:class:`MPC`). The worlds come from :class:`wfbench.core.belief.Belief`: they agree with every
observation and draw the unobserved from the public model under the policy's own keys. The
oracles that read the true future are :mod:`wfbench.policies.oracle`. ``docs/policies.md``,
"Lookahead policies".
"""

from typing import Any

from wfbench.policies.lookahead.mpc import MPC
from wfbench.policies.lookahead.network_rollout import NetworkRollout
from wfbench.policies.lookahead.rollout import BUDGETS, DEFAULT_BUDGET, Rollout, budget, knob
from wfbench.policies.lookahead.search import NetworkSearch
from wfbench.policies.lookahead.search import make as search_preset


def make(base: Any, budget_name: str = DEFAULT_BUDGET, name: str | None = None, **knobs: Any) -> Any:
    """A rollout of ``base`` at a budget preset, knobs overriding it.

    :class:`Rollout` of a compiled composite, :class:`NetworkRollout` of a network; a budget
    ``search:NAME`` is :class:`NetworkSearch` of a network at its preset NAME.
    """
    if budget_name.startswith("search:"):
        return search_preset(base, budget_name[len("search:"):], name=name, **knobs)
    if not getattr(base, "compiled", False) and hasattr(base, "model"):
        return NetworkRollout(base, budget=budget_name, name=name, **knobs)
    return Rollout(base, budget=budget_name, name=name, **knobs)


__all__ = ["BUDGETS", "DEFAULT_BUDGET", "MPC", "NetworkRollout", "NetworkSearch", "Rollout", "budget", "knob", "make"]
