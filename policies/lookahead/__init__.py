"""Deployable lookahead policies (issue #43): they plan on worlds sampled from what they observe.

:mod:`~wfbench.policies.lookahead.rollout` rolls a compiled base policy forward on K sampled
futures (:class:`Rollout`, :data:`BUDGETS`); :mod:`~wfbench.policies.lookahead.network_rollout`
does it with a trained network as the base (:class:`NetworkRollout`);
:mod:`~wfbench.policies.lookahead.search` searches with the network, greedy futures ended at its
value and a noise test (:class:`NetworkSearch`), and
:mod:`~wfbench.policies.lookahead.playout` with its futures played to the end (:class:`PlayoutSearch`);
:mod:`~wfbench.policies.lookahead.mpc` solves a rolling-horizon staffing MILP on a forecast
(:class:`MPC`). The worlds come from :class:`wfbench.core.belief.Belief`: they agree with every
observation and draw the unobserved from the public model under the policy's own keys. The
oracles that read the true future are :mod:`wfbench.policies.oracle`. ``docs/policies.md``,
"Lookahead policies".

This package registers its presets (:data:`PRESETS`, below) in :mod:`wfbench.policies.table`
and imports its modules on first use of their names (PEP 562), so that the registry, which
imports it, stays cheap to import.
"""

from __future__ import annotations

from typing import Any

from wfbench.policies.table import (
    SINCE_V2,
    SINCE_V3,
    Entry,
    MPCPreset,
    RolloutPreset,
    SearchPreset,
    SwitchPreset,
    TunedLookahead,
    register,
)

from wfbench.core import lazy

# name -> the module that defines it: imported when the name is first read
_LAZY = {"MPC": ".mpc", "NetworkRollout": ".network_rollout", "BUDGETS": ".rollout", "DEFAULT_BUDGET": ".rollout",
         "Rollout": ".rollout", "budget": ".rollout", "knob": ".rollout", "NetworkSearch": ".search",
         "PlayoutSearch": ".playout", "SeedSwitch": ".switch"}
__getattr__, __dir__ = lazy.names(__name__, _LAZY)


def make(base: Any, budget_name: str | None = None, name: str | None = None, **knobs: Any) -> Any:
    """A rollout of ``base`` at a budget preset (None: the default), knobs overriding it.

    :class:`Rollout` of a compiled composite, :class:`NetworkRollout` of a network; a budget
    ``search:NAME`` is :class:`NetworkSearch` of a network at its preset NAME.
    """
    from wfbench.policies.lookahead import network_rollout, rollout, search

    budget_name = rollout.DEFAULT_BUDGET if budget_name is None else budget_name
    if budget_name.startswith("search:"):
        return search.make(base, budget_name[len("search:"):], name=name, **knobs)
    if not getattr(base, "compiled", False) and hasattr(base, "model"):
        return network_rollout.NetworkRollout(base, budget=budget_name, name=name, **knobs)
    return rollout.Rollout(base, budget=budget_name, name=name, **knobs)


# -- the presets, by name (wfbench.policies.table; docs/policies.md, "Lookahead policies") ---------------------------
# Asked for by name (get, parse_spec), not listed: names(), deployable_names() and the leaderboard's seeding leave
# them out, as issue #43 did with the frontier; oracle-v2 plays those registered when it was made (candidate_of)

# a rollout of a compiled base on K sampled futures of H steps, one name per budget preset
# (wfbench.policies.lookahead.rollout.BUDGETS); the network as the base costs far more at the same knobs (H forward
# passes a decision). sparse, for city (issue #53): the budget's knobs on solver-tuned's sparse twin (its tuned
# parameters, assignment and p-median on the k nearest), a decision every R steps only, the futures positioned by
# spatial averaging (docs/policies.md, "Lookahead policies on city"); "auto" plays that on a world as large as city and
# the dense rollout, bit for bit, on every other world (issue #53)
ROLLOUTS = (
    Entry("rollout-solver-tuned", "rollout", RolloutPreset("solver-tuned", "10ms", sparse="auto"),
          "rollout of solver-tuned on sampled futures (K=4, H=80, R=20); on city, its sparse preset",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-solver-tuned-1ms", "rollout", RolloutPreset("solver-tuned", "1ms", sparse="auto"),
          "rollout of solver-tuned, the 1 ms budget (K=2, H=80, R=80); on city, its sparse preset",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-solver-tuned-100ms", "rollout", RolloutPreset("solver-tuned", "100ms", sparse="auto"),
          "rollout of solver-tuned, the 100 ms budget (K=16, H=120, R=10); on city, its sparse "
          "preset",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-scalefree-general", "rollout", RolloutPreset("scalefree-general", "1ms"),
          "rollout of the scale-free network on sampled futures, the network playing them (K=2, H=80, R=80)",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-solver-sparse-tuned", "rollout", RolloutPreset("solver-tuned", "10ms", sparse=True),
          "rollout of solver-tuned's sparse twin, for city: K=4, H=80, a decision every R=20 steps, spatial "
          "positioning in the futures",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-solver-sparse-tuned-1ms", "rollout", RolloutPreset("solver-tuned", "1ms", sparse=True),
          "rollout-solver-sparse-tuned at the 1 ms budget (K=2, H=80, R=80)",
          listed=False, candidate_of=SINCE_V2),
    Entry("rollout-solver-sparse-tuned-100ms", "rollout", RolloutPreset("solver-tuned", "100ms", sparse=True),
          "rollout-solver-sparse-tuned at the 100 ms budget (K=16, H=120, R=10)",
          listed=False, candidate_of=SINCE_V2),
)

# the rolling-horizon MILP (issue #43; docs/policies.md, "mpc"): the base plays dispatch (its assignment), the MILP
# staffs and positions on the forecast; "calibrated" measures its capacity from observed repairs (issue #53, "Why it
# churns"), "backlog" adds a fluid queue of repair requests (issue #53's second design); the tuned ones are the
# untuned presets with a tuned-policy file's parameters, tuned on suite-v1's training split, public seeds 1000-1004
MPCS = (
    Entry("mpc-rates", "mpc", MPCPreset("solver-tuned-train", "rates"),
          "rolling-horizon staffing MILP (HiGHS) on the public rates and schedules, H=100, re-solved every R=20 "
          "steps; assignment dispatch",
          listed=False, candidate_of=SINCE_V2),
    Entry("mpc-ma", "mpc", MPCPreset("solver-tuned-train", "ma"),
          "rolling-horizon staffing MILP (HiGHS) on a 100-step moving average of observed requests (no demand "
          "model), H=100, R=20; assignment dispatch",
          listed=False, candidate_of=SINCE_V2),
    Entry("mpc-rates-calibrated", "mpc", MPCPreset("solver-tuned-train", "rates", "calibrated"),
          "mpc-rates with the capacity per person measured from observed repairs and the working share averaged "
          "over the window",
          listed=False, candidate_of=SINCE_V2),
    Entry("mpc-ma-calibrated", "mpc", MPCPreset("solver-tuned-train", "ma", "calibrated"),
          "mpc-ma with the capacity per person measured from observed repairs; the base staffs until a window of "
          "requests is seen",
          listed=False, candidate_of=SINCE_V2),
    Entry("mpc-rates-backlog", "mpc", MPCPreset("solver-tuned-train", "rates", "backlog"),
          "mpc-rates-calibrated whose MILP carries the repair backlog (a fluid queue seeded from the waiting "
          "requests, priced as downtime)",
          listed=False, candidate_of=SINCE_V3),
    Entry("mpc-ma-backlog", "mpc", MPCPreset("solver-tuned-train", "ma", "backlog"),
          "mpc-ma-calibrated whose MILP carries the repair backlog (a fluid queue seeded from the waiting requests, "
          "priced as downtime)",
          listed=False, candidate_of=SINCE_V3),
    Entry("mpc-rates-tuned-train", "mpc", TunedLookahead("mpc-rates", "mpc-rates-suite-v1-train.json"),
          "mpc-rates with its knobs, prices and capacity scale tuned on suite-v1's training split (wfbench tune)",
          listed=False, candidate_of=SINCE_V2),
    Entry("mpc-ma-tuned-train", "mpc", TunedLookahead("mpc-ma", "mpc-ma-suite-v1-train.json"),
          "mpc-ma with its knobs, prices and capacity scale tuned on suite-v1's training split (wfbench tune)",
          listed=False, candidate_of=SINCE_V2),
)

# search with the network (issue #52; docs/policies.md, "search-scalefree-general"): a budget preset of
# wfbench.policies.lookahead.search (greedy futures ended at the network's value, a noise test)
SEARCHES = (
    Entry("search-scalefree-general-1ms", "search", SearchPreset("scalefree-general", "1ms"),
          "search with the scale-free network, the 1 ms budget (K=2, H=10, R=80, top=2, z=1)",
          listed=False, candidate_of=SINCE_V2),
    Entry("search-scalefree-general", "search", SearchPreset("scalefree-general", "10ms"),
          "search with the scale-free network: greedy futures ended at its value, a noise test (K=8, H=20, R=20, "
          "top=3, z=1)",
          listed=False, candidate_of=SINCE_V2),
    Entry("search-scalefree-general-100ms", "search", SearchPreset("scalefree-general", "100ms"),
          "search with the scale-free network, the 100 ms budget (K=32, H=20, R=10, top=4, z=1)",
          listed=False, candidate_of=SINCE_V2),
    # registered after oracle-v2's candidates were fixed; v3 leaves it out (0.1-0.5 s per env-step, pieces of 20 seeds
    # on four worlds: docs/hindsight.md, "Versioned references"), so the suite's check names it where it is above v3
    Entry("search-scalefree-general-playout", "search", SearchPreset("scalefree-general", "100ms", playout=True),
          "search with the scale-free network, its greedy futures played to the episode's end, no critic (K=4, "
          "R=20, top=3, z=1); on city, the 10 ms search",
          listed=False),
)

# the learned side choosing among its own networks (issue #52; docs/policies.md, "switch-scalefree-general"): the
# method's training seeds played on the same sampled futures to the episode's end, each environment following the best
# beyond the noise. Registered after v3's candidates were fixed: no reference plays it
SWITCHES = (
    Entry("switch-scalefree-general", "search", SwitchPreset("scalefree-general", "10ms"),
          "the scale-free network's five training seeds played on the same sampled futures to the episode's end, "
          "following the best beyond the noise (K=4 futures, once at the start, z=1)",
          decisions=("PPO (scale-free), seed switched",) * 3, listed=False),
    Entry("switch-scalefree-general-5ms", "search", SwitchPreset("scalefree-general", "5ms"),
          "the scale-free network's five training seeds played on the same sampled futures to the episode's end, "
          "following the best beyond the noise, the 5 ms budget (K=2 futures, once at the start, z=1)",
          decisions=("PPO (scale-free), seed switched",) * 3, listed=False),
)

# in the order lookahead_names() has always given (the rollouts of issue #43, the city presets, the MPCs, the search),
# then the switch
PRESETS = (*ROLLOUTS, *MPCS, *SEARCHES, *SWITCHES)
register(*PRESETS)

__all__ = ["BUDGETS", "DEFAULT_BUDGET", "MPC", "MPCS", "PRESETS", "ROLLOUTS", "SEARCHES", "SWITCHES", "NetworkRollout",
           "NetworkSearch", "PlayoutSearch", "Rollout", "SeedSwitch", "budget", "knob", "make"]
