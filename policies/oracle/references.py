"""Named, versioned references: which candidates each best-in-hindsight oracle plays, listed once, never changed.

A reference is a literal tuple of registry names, in the order that breaks ties (the first
wins). Publishing a number with a reference freezes nothing but that tuple: a policy added
to the registry later enters a *new* version, never an existing one, so a published
reference does not move. :data:`ORACLES` names each oracle of the registry by its
reference. ``v1`` is the candidate list of the ``oracle`` that made every table up to issue
#53 (the suite, Table 3, the gap), entry for entry; ``v2`` takes every deployable family,
the lookahead presets included, and the hindsight rollout (``oracle-rollout``,
:mod:`wfbench.policies.oracle.hindsight`); ``v3`` adds the deployable policies v2 does not
play: the MPCs on the repair backlog, ``distill-general``, and every learned method's other
training seeds (``METHOD#seedK``, a policy as deployable as its method's shipped pick).
``docs/hindsight.md``, "Versioned references".

This module is below the registry (``wfbench.policies`` layers): it holds the lists,
builds an oracle from a ``resolve`` function the registry hands it, and registers the
oracles that are not composites in :data:`wfbench.policies.table.TABLE` (the planner's
composites, ``oracle-planner`` and ``oracle-dispatch``, are the registry's).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from wfbench.policies.oracle.best import BestInHindsight
from wfbench.policies.table import BestOf, Entry, HindsightRolloutOf, register

# the oracle of every table published up to issue #53: the compiled built-ins, the planner, the shipped networks
V1: tuple[str, ...] = (
    "random", "heuristic", "heuristic-stochastic", "random-dispatch", "random-positioning", "fixed-workforce",
    "solver", "solver-dispatch", "solver-workforce", "solver-positioning", "heuristic-tuned", "solver-tuned",
    "oracle-planner",
    "ppo-joint", "ppo-dispatch", "impala-joint", "hindsight-joint", "ppo-independent", "hindsight-ppo", "ppo-general",
    "hindsight-general",
)

# every deployable family of issue #53: v1's candidates in v1's order, the compiled policies v1 left out, the hindsight
# rollout, the scale-free network, then every lookahead preset (rollouts, MPCs, the network's search)
V2: tuple[str, ...] = (
    *V1[:12],  # the compiled built-ins of v1
    "solver-sparse", "heuristic-tuned-train", "solver-tuned-train",
    "oracle-rollout", "oracle-planner",
    *V1[13:],  # the networks of v1
    "scalefree-general",
    "rollout-solver-tuned-1ms", "rollout-solver-tuned", "rollout-solver-tuned-100ms",
    "rollout-solver-sparse-tuned-1ms", "rollout-solver-sparse-tuned", "rollout-solver-sparse-tuned-100ms",
    "rollout-scalefree-general",
    "mpc-rates", "mpc-ma", "mpc-rates-calibrated", "mpc-ma-calibrated", "mpc-rates-tuned-train", "mpc-ma-tuned-train",
    "search-scalefree-general-1ms", "search-scalefree-general", "search-scalefree-general-100ms",
)

# every deployable policy with a suite piece when issue #53 found v2 below a training seed of scalefree-general
# (table2-g256-f25-s5-v1, table2-g32-f100-s25-v1): v2's candidates in v2's order, the policies registered after v2,
# then the training seeds of each method trained over seeds (wfbench.policies.registry.seed_runs), less the seed its
# shipped pick is a copy of (ppo-general#seed3, hindsight-general#seed4, scalefree-general#seed2,
# distill-general#seed3: the same file plays the same episodes, and v2 plays the pick first)
V3: tuple[str, ...] = (
    *V2,
    "mpc-rates-backlog", "mpc-ma-backlog", "distill-general",
    "ppo-general#seed0", "ppo-general#seed1", "ppo-general#seed2", "ppo-general#seed4",
    "hindsight-general#seed0", "hindsight-general#seed1", "hindsight-general#seed2", "hindsight-general#seed3",
    "scalefree-general#seed0", "scalefree-general#seed1", "scalefree-general#seed3", "scalefree-general#seed4",
    "distill-general#seed0", "distill-general#seed1", "distill-general#seed2", "distill-general#seed4",
)

REFERENCES: dict[str, tuple[str, ...]] = {"v1": V1, "v2": V2, "v3": V3}

# registry name -> its reference: what each best-in-hindsight oracle of the registry plays
ORACLES: dict[str, str] = {"oracle": "v1", "oracle-v2": "v2", "oracle-v3": "v3"}
# the references whose oracle also takes totals from committed suite pieces and replays recorded episodes
# (BestInHindsight(replay=True)); v1 plays as it always did, so its numbers stay bit for bit
REPLAYING = frozenset({"v2", "v3"})


def reference(name: str) -> str:
    """The reference of an oracle's registry name, or a reference's own name; ValueError of one line otherwise."""
    if name in ORACLES:
        return ORACLES[name]
    if name in REFERENCES:
        return name
    raise ValueError(f"{name!r} is neither a best-in-hindsight oracle nor a reference; allowed: "
                     f"{', '.join([*ORACLES, *REFERENCES])}")


def candidates(name: str = "oracle", available: Callable[[str], bool] | None = None) -> list[str]:
    """The candidates of an oracle or reference, in tie-breaking order, those ``available`` says are installed.

    ``available`` is the registry's test of a name (a shipped network is offered only when its
    checkpoint is there); None keeps every name.
    """
    listed = REFERENCES[reference(name)]
    return [n for n in listed if available is None or available(n)]


def outside(policy: str, name: str = "oracle") -> bool:
    """Whether ``policy`` is not a candidate of the oracle or reference ``name``."""
    return policy not in REFERENCES[reference(name)]


def replayed() -> frozenset[str]:
    """The candidates of every replaying reference: the names whose episodes the runner records as it plays them."""
    return frozenset(n for ref in REPLAYING for n in REFERENCES[ref])


def make(name: str, resolve: Callable[[str], Any], available: Callable[[str], bool] | None = None,
         inputs: Callable[[str], list] | None = None) -> BestInHindsight:
    """The best-in-hindsight oracle ``name`` (:data:`ORACLES`) over its reference's available candidates.

    ``inputs``: the files besides code a candidate reads (``wfbench.policies.registry.input_files``),
    which a replaying reference checks the committed pieces against.
    """
    ref = reference(name)
    return BestInHindsight(candidates(ref, available), resolve, name=name, replay=ref in REPLAYING, inputs=inputs)


# the oracles that are not composites, by name (docs/hindsight.md, "The oracle"): each reads the trace
HINDSIGHT = ("Hindsight oracle",) * 3  # how tables name its three decisions
register(
    Entry("oracle", "oracle", BestOf("v1"),
          "per seed, the best in hindsight of oracle-planner and every deployable built-in (the composites, the tuned "
          "files and the shipped networks): reads the trace, not deployable (docs/hindsight.md)",
          decisions=HINDSIGHT, reads_future=True),
    Entry("oracle-v2", "oracle", BestOf("v2"),
          "reference v2: per seed, the best in hindsight of every deployable family, the lookaheads included, and "
          "oracle-rollout; replays recorded episodes and committed pieces (docs/hindsight.md)",
          decisions=HINDSIGHT, reads_future=True),
    Entry("oracle-v3", "oracle", BestOf("v3"),
          "reference v3: per seed, the best in hindsight of v2's candidates, the policies registered since and every "
          "learned method's training seeds; replays recorded episodes and committed pieces (docs/hindsight.md)",
          decisions=HINDSIGHT, reads_future=True),
    Entry("oracle-rollout", "oracle", HindsightRolloutOf("solver-tuned"),
          "the rollout of solver-tuned on the true future, rolled to the end of the episode (on city, the rollout's "
          "city preset: the sparse twin every 20 steps, spatial futures): reads the trace, not deployable "
          "(docs/hindsight.md, \"The hindsight rollout\")",
          decisions=HINDSIGHT, reads_future=True, candidate_of=("v2", "v3")),
)

__all__ = ["HINDSIGHT", "ORACLES", "REFERENCES", "REPLAYING", "V1", "V2", "V3", "candidates", "make", "outside",
           "reference", "replayed"]
