"""The one table of policies: each registered name is one :class:`Entry`, registered by its family's module.

An entry holds a policy's name, its family, how it is built (a typed *recipe*: the dataclasses
below, one per way of building), a one-line summary, how tables name its three decisions,
whether it reads the future, whether it is listed, the references of the best-in-hindsight
oracle that play it; its budget class is read from ``budgets.json`` beside this module (what the
committed frontier measured, written by ``wfbench reproduce frontier --classes``), data rather
than code, so that a new measurement edits no source file. The families register
their own entries, the way Gymnasium's ``register`` fills its registry of ``EnvSpec``:
the composites in :mod:`wfbench.policies.registry`, the tuned files in
:mod:`wfbench.policies.tuned`, the networks in :mod:`wfbench.policies.neural`, the
lookahead presets (rollouts, MPCs, searches) in :mod:`wfbench.policies.lookahead`, the
oracles in :mod:`wfbench.policies.oracle.references`. This module is at the bottom of
``wfbench.policies`` and imports nothing of wfbench, so that every family can register here
without an import cycle and without importing what builds its policies;
:mod:`wfbench.policies.registry` reads the table and builds (``docs/policies.md``,
"Listing policies").
"""

from __future__ import annotations

import difflib
import enum
import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import ClassVar

# the families, in the order ``wfbench policies`` lists them -> what their policies are, in one line
FAMILIES: dict[str, str] = {
    "composite": "built-in decisions put together (Composite; D+W+P names any three)",
    "tuned": "a composite with the parameters wfbench tune chose (a file under policies/tuned/)",
    "learned": "trained networks (policies/neural/checkpoints/; loading them needs torch)",
    "rollout": "lookahead: a base rolled out on futures sampled from what it observed",
    "mpc": "lookahead: a rolling-horizon staffing MILP on a forecast, the base dispatching",
    "search": "lookahead: the network's search on greedy futures, ended at its value or played out, or a switch "
              "among its training seeds",
    "oracle": "hindsight: reads the episode's trace, not deployable (docs/hindsight.md)",
}
KINDS: tuple[str, ...] = ("composite", "oracle", "tuned", "learned", "lookahead")  # a recipe's kind (parse_spec's)


class Budget(enum.Enum):
    """A budget class: the CPU ms per env-step a policy was measured at (``wfbench reproduce frontier``).

    The buckets are the frontier's budgets (:data:`wfbench.reproduce.frontier.BUDGETS_MS`) and
    what lies above the largest.
    """

    MS_1 = "<= 1 ms"
    MS_10 = "<= 10 ms"
    MS_100 = "<= 100 ms"
    MORE = "> 100 ms"

    @classmethod
    def of(cls, cpu_ms_per_step: float) -> Budget:
        """The class of a measured cost (CPU ms per env-step)."""
        for limit, budget in ((1.0, cls.MS_1), (10.0, cls.MS_10), (100.0, cls.MS_100)):
            if cpu_ms_per_step <= limit:
                return budget
        return cls.MORE


NOT_MEASURED = "not measured"
BUDGETS_FILE = Path(__file__).with_name("budgets.json")  # the committed frontier's cost of each policy it measured


@cache
def measured_costs() -> dict[str, float]:
    """CPU ms per env-step of each policy the committed frontier measured (:data:`BUDGETS_FILE`; empty without one)."""
    if not BUDGETS_FILE.is_file():
        return {}
    return {name: float(ms) for name, ms in json.loads(BUDGETS_FILE.read_text())["cpu_ms_per_step"].items()}


# -- recipes: how a policy is built, one dataclass per way ---------------------------------------------------------

@dataclass(frozen=True)
class CompositeOf:
    """A :class:`wfbench.policies.composite.Composite` of three built-in decisions (``DECISIONS``' names)."""

    kind: ClassVar[str] = "composite"
    dispatch: str
    workforce: str
    positioning: str

    def describe(self) -> str:
        return f"dispatch={self.dispatch}, workforce={self.workforce}, positioning={self.positioning}"


@dataclass(frozen=True)
class TunedFile:
    """A tuned-policy file shipped under ``policies/tuned/`` (its base and parameters are in the file)."""

    kind: ClassVar[str] = "tuned"
    file: str

    def describe(self) -> str:
        return f"policies/tuned/{self.file}"


@dataclass(frozen=True)
class Checkpoint:
    """A trained network shipped under ``policies/neural/checkpoints/`` (loading it needs torch).

    ``seeds`` are the checkpoint files of its training seeds, the same command with only the
    seed varied (``METHOD#seedK``; docs/suite.md, "Learned methods over training seeds"), of which
    ``file`` is a byte copy of the median one; empty when it was trained once.
    """

    kind: ClassVar[str] = "learned"
    file: str
    seeds: tuple[str, ...] = ()

    def describe(self) -> str:
        return f"policies/neural/checkpoints/{self.file}"


@dataclass(frozen=True)
class BestOf:
    """The best in hindsight, per seed, of the candidates of a versioned reference (``v1``, ``v2``)."""

    kind: ClassVar[str] = "oracle"
    reference: str

    def describe(self) -> str:
        return f"the best in hindsight of reference {self.reference}'s candidates"


@dataclass(frozen=True)
class HindsightRolloutOf:
    """The rollout of ``base`` on the true future, to the end of the episode (``oracle-rollout``)."""

    kind: ClassVar[str] = "oracle"
    base: str

    def describe(self) -> str:
        return f"the rollout of {self.base} on the true future"


@dataclass(frozen=True)
class RolloutPreset:
    """A rollout of ``base`` on sampled futures at a budget preset (``1ms``, ``10ms``, ``100ms``).

    ``sparse``: True, the city preset, on the sparse twin of ``base``, a decision every R steps
    only, the futures positioned by spatial averaging (``Rollout(budget="sparse:BUDGET")``);
    ``"auto"``, that preset on a world as large as city and the dense rollout on any other
    (``Rollout(sparse="auto")``); False, the dense rollout everywhere.
    """

    kind: ClassVar[str] = "lookahead"
    base: str
    budget: str
    sparse: bool | str = False

    def __post_init__(self) -> None:
        if not (self.sparse is True or self.sparse is False or self.sparse == "auto"):
            raise ValueError(f"rollout preset sparse = {self.sparse!r} is not allowed; allowed: False, True, 'auto'")

    def describe(self) -> str:
        where = {True: ", sparse (for city)", "auto": ", sparse on city-sized worlds"}.get(self.sparse, "")
        return f"a lookahead on {self.base}, the {self.budget} preset{where}"


@dataclass(frozen=True)
class MPCPreset:
    """The rolling-horizon staffing MILP on a ``forecast`` (``rates``, ``ma``), ``base`` playing dispatch.

    ``option``: ``""``, ``"calibrated"`` (capacity measured from observed repairs) or
    ``"backlog"`` (calibrated, with the repair backlog in the MILP); the knobs each sets are
    :data:`wfbench.policies.lookahead.mpc.PRESET_OPTIONS`.
    """

    kind: ClassVar[str] = "lookahead"
    OPTIONS: ClassVar[tuple[str, ...]] = ("", "calibrated", "backlog")
    base: str
    forecast: str
    option: str = ""

    def describe(self) -> str:
        return f"a lookahead on {self.base}, the MILP on forecast {self.forecast}" + \
            (f", {self.option}" if self.option else "")

    def __post_init__(self) -> None:
        if self.option not in self.OPTIONS:
            raise ValueError(f"mpc preset option {self.option!r} is not allowed; allowed: "
                             f"{', '.join(repr(o) for o in self.OPTIONS)}")


@dataclass(frozen=True)
class TunedLookahead:
    """A lookahead ``base`` (a registered preset) with the parameters of a tuned-policy file under policies/tuned/."""

    kind: ClassVar[str] = "lookahead"
    base: str
    file: str

    def describe(self) -> str:
        return f"a lookahead on {self.base}, tuned: policies/tuned/{self.file}"


@dataclass(frozen=True)
class SearchPreset:
    """The network ``base``'s search (greedy futures ended at its value, a noise test) at a budget preset.

    ``playout``: the futures are played to the episode's end instead (no value), ``budget`` a
    preset of :data:`wfbench.policies.lookahead.playout.BUDGETS`; else of
    :data:`wfbench.policies.lookahead.search.BUDGETS`.
    """

    kind: ClassVar[str] = "lookahead"
    base: str
    budget: str
    playout: bool = False

    def describe(self) -> str:
        return f"a lookahead on {self.base}, the {'played-out ' if self.playout else ''}search's {self.budget} preset"


@dataclass(frozen=True)
class SwitchPreset:
    """A switch among the training seeds of the network ``base`` (its shipped pick first) at a budget preset.

    ``budget``: a preset of :data:`wfbench.policies.lookahead.switch.BUDGETS`.
    """

    kind: ClassVar[str] = "lookahead"
    base: str
    budget: str

    def describe(self) -> str:
        return f"a lookahead on {self.base}'s training seeds, the switch's {self.budget} preset"


Recipe = CompositeOf | TunedFile | Checkpoint | BestOf | HindsightRolloutOf | RolloutPreset | MPCPreset | \
    TunedLookahead | SearchPreset | SwitchPreset


# Entry.candidate_of by when a policy was registered: each reference after v1 plays every policy of the one before it
# (wfbench.policies.oracle.references), so a policy is a candidate from its first reference on
SINCE_V1 = ("v1", "v2", "v3")
SINCE_V2 = ("v2", "v3")
SINCE_V3 = ("v3",)


@dataclass(frozen=True)
class Entry:
    """One registered policy (module docstring).

    Attributes:
        name: what ``policies.get`` takes.
        family: one of :data:`FAMILIES`.
        recipe: how it is built (one of the recipe dataclasses; its ``kind`` is ``parse_spec``'s).
        summary: one line for ``wfbench policies``.
        decisions: how tables name its dispatch, workforce and positioning (Table 3's columns);
            empty when they follow from its recipe (a composite's decisions, a tuned file's or
            lookahead's base: :func:`wfbench.policies.registry.parts`).
        reads_future: it reads the episode's trace (an oracle), so it is not deployable.
        listed: in ``policies.names()`` (the policies the tables, the leaderboard and the
            command line's ``all`` run); the lookaheads are asked for by name only.
        candidate_of: the references (``v1``, ``v2``, ``v3``) whose best-in-hindsight oracle plays it, as
            :mod:`wfbench.policies.oracle.references` lists them in tie-breaking order; a test
            checks the two agree, so that registering a policy never moves a published number.

    Its budget class (:attr:`budget`) is not a field: it is measured, and read from
    :data:`BUDGETS_FILE`.
    """

    name: str
    family: str
    recipe: Recipe
    summary: str
    decisions: tuple[str, ...] = ()
    reads_future: bool = False
    listed: bool = True
    candidate_of: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ValueError(f"policy {self.name!r}: family {self.family!r} is not allowed; allowed: "
                             f"{', '.join(FAMILIES)}")
        if self.decisions and len(self.decisions) != 3:
            raise ValueError(f"policy {self.name!r}: decisions names {len(self.decisions)} labels; allowed: "
                             "three (dispatch, workforce, positioning) or none")
        if not self.decisions and isinstance(self.recipe, Checkpoint | BestOf | HindsightRolloutOf):
            raise ValueError(f"policy {self.name!r}: a {type(self.recipe).__name__} has no decisions to take its "
                             "labels from; allowed: three labels (dispatch, workforce, positioning)")

    @property
    def kind(self) -> str:
        """How ``parse_spec`` reads its name: one of :data:`KINDS`."""
        return self.recipe.kind

    @property
    def oracle_candidate(self) -> bool:
        """Whether a best-in-hindsight oracle plays it."""
        return bool(self.candidate_of)

    @property
    def budget(self) -> Budget | None:
        """Its measured budget class (:func:`measured_costs`), None when the committed frontier did not measure it."""
        ms = measured_costs().get(self.name)
        return None if ms is None else Budget.of(ms)

    @property
    def budget_class(self) -> str:
        """Its budget class as ``wfbench policies`` prints it, or ``not measured``."""
        return NOT_MEASURED if self.budget is None else self.budget.value


# name -> entry, in the order of registration (each family registers its own in its own order)
TABLE: dict[str, Entry] = {}


def register(*entries: Entry) -> None:
    """Add entries to :data:`TABLE`; a name registered twice is refused (a module imported once registers once)."""
    for e in entries:
        if e.name in TABLE and TABLE[e.name] != e:
            raise ValueError(f"policy {e.name!r} is already registered (family {TABLE[e.name].family}); "
                             "allowed: a name not in the table")
        TABLE[e.name] = e


def closest(name: str, n: int = 3) -> list[str]:
    """The registered names closest to ``name`` (any family), best first; empty if none is close."""
    return difflib.get_close_matches(name, list(TABLE), n=n)


__all__ = ["FAMILIES", "KINDS", "NOT_MEASURED", "TABLE", "BestOf", "Budget", "Checkpoint", "CompositeOf", "Entry",
           "HindsightRolloutOf", "MPCPreset", "Recipe", "RolloutPreset", "SearchPreset", "SwitchPreset", "TunedFile",
           "TunedLookahead", "closest", "register"]
