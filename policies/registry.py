"""Policies by name: the registered ones, ``"D+W+P"`` composites of built-in decisions, tuned-policy files.

And ``module:attr`` entry points. The registered names are one table,
:data:`wfbench.policies.table.TABLE`, of :class:`~wfbench.policies.table.Entry` rows: this
module registers the composites and imports the families that register theirs (the tuned
files, the networks, the lookahead presets, the oracles), then reads the table to list and
build (``docs/policies.md``, "Listing policies").
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wfbench.policies import lookahead as _lookahead_family  # noqa: F401  (registers the lookahead presets)
from wfbench.policies import tuned as _tuned
from wfbench.policies.composite import Composite
from wfbench.policies.neural import CHECKPOINT_ALGORITHMS
from wfbench.policies.oracle import references as _references  # noqa: F401  (registers the oracles)
from wfbench.policies.table import (
    FAMILIES,
    SINCE_V1,
    SINCE_V2,
    TABLE,
    BestOf,
    Checkpoint,
    CompositeOf,
    Entry,
    HindsightRolloutOf,
    MPCPreset,
    SearchPreset,
    SwitchPreset,
    TunedFile,
    TunedLookahead,
    register,
)

from wfbench.core.paths import CHECKPOINTS, data_path

# the composites of built-in decisions, by name (wfbench.policies.table; the other families register in their own
# modules: the tuned files in wfbench.policies.tuned, the networks in wfbench.policies.neural, the lookahead presets in
# wfbench.policies.lookahead, the oracles that are not composites in wfbench.policies.oracle.references)
register(
    Entry("random", "composite", CompositeOf("random", "random", "random"),
          "uniformly random valid actions for all three decisions (Table 3 row 1)", candidate_of=SINCE_V1),
    Entry("heuristic", "composite", CompositeOf("nearest", "threshold", "spatial"),
          "the paper's deterministic heuristics (Table 3 row 4)", candidate_of=SINCE_V1),
    Entry("heuristic-stochastic", "composite", CompositeOf("inverse-distance", "threshold-epsilon", "spatial-gaussian"),
          "the stochastic variants of the heuristics", candidate_of=SINCE_V1),
    Entry("random-dispatch", "composite", CompositeOf("random", "threshold", "spatial"),
          "random dispatch, heuristic workforce and positioning (row 2)", candidate_of=SINCE_V1),
    Entry("random-positioning", "composite", CompositeOf("nearest", "threshold", "random"),
          "heuristic dispatch and workforce, random positioning (row 3)", candidate_of=SINCE_V1),
    Entry("fixed-workforce", "composite", CompositeOf("nearest", "fixed", "none"),
          "nearest dispatch, no hiring or letting go (Table 2)", candidate_of=SINCE_V1),
    Entry("solver", "composite", CompositeOf("assignment", "staffing", "facility-location"),
          "the three solver-backed decisions (docs/solvers.md)", candidate_of=SINCE_V1),
    Entry("solver-dispatch", "composite", CompositeOf("assignment", "threshold", "spatial"),
          "optimal-assignment dispatch, heuristic workforce and positioning", candidate_of=SINCE_V1),
    Entry("solver-workforce", "composite", CompositeOf("nearest", "staffing", "spatial"),
          "square-root staffing, heuristic dispatch and positioning", candidate_of=SINCE_V1),
    Entry("solver-positioning", "composite", CompositeOf("nearest", "threshold", "facility-location"),
          "p-median positioning, heuristic dispatch and workforce", candidate_of=SINCE_V1),
    # the hindsight planner's composites: the oracle family, read as composites
    Entry("oracle-planner", "oracle", CompositeOf("oracle", "oracle", "oracle"),
          "the hindsight planner for all three decisions: reads the trace, not deployable (docs/hindsight.md)",
          reads_future=True, candidate_of=SINCE_V1),
    Entry("oracle-dispatch", "oracle", CompositeOf("oracle", "threshold", "spatial"),
          "hindsight dispatch, heuristic workforce and positioning: not deployable", reads_future=True),
    # added after the published tables: opt-in, a candidate from oracle-v2 on
    Entry("solver-sparse", "composite", CompositeOf("assignment-sparse", "staffing", "facility-location-sparse"),
          "the solver composite with its assignment and p-median solved on sparse candidate graphs (the k nearest; "
          "docs/solvers.md, \"Sparse candidate graphs\")", candidate_of=SINCE_V2),
)
CHECKPOINT_DIR = data_path(CHECKPOINTS)  # policies/neural/checkpoints/ (wfbench/policies/... in a wheel)


def entry(name: str) -> Entry:
    """The registered entry of ``name``; ValueError of one line with the closest names otherwise."""
    if name in TABLE:
        return TABLE[name]
    raise ValueError(unknown_message(name, "registered policy"))


def entries(family: str | None = None) -> list[Entry]:
    """Every registered entry, grouped by family in :data:`FAMILIES`' order, or those of ``family``.

    Raises:
        ValueError: an unknown family; the message names the allowed ones.
    """
    if family is not None and family not in FAMILIES:
        raise ValueError(f"unknown policy family {family!r}; allowed: {', '.join(FAMILIES)}")
    return [e for f in FAMILIES if family in (None, f) for e in TABLE.values() if e.family == f]


def unknown_message(name: str, what: str = "policy", also: str = "") -> str:
    """One line for a name that is not registered: every registered name (by family), then the closest of them.

    ``also`` names the other forms allowed where the name was read (", a tuned-policy file ...").
    The suggestion is difflib's, over every family (lookaheads and oracles included).
    """
    close = [repr(n) for n in difflib.get_close_matches(name, list(TABLE), n=3) if n != name]
    hint = "" if not close else "; did you mean " + (close[0] if len(close) == 1 else
                                                    f"{', '.join(close[:-1])} or {close[-1]}") + "?"
    return f"unknown {what} {name!r}; available: {', '.join(e.name for e in entries())}{also}{hint}"


def names_of(kind: str) -> list[str]:
    """Every registered name whose recipe is of ``kind`` (``parse_spec``'s), in registration order.

    ``kind`` is composite, oracle, tuned, learned or lookahead; the networks are named whether
    their checkpoint is shipped or not (:func:`learned_names`: those that are).
    """
    return _of_kind(kind)


def _of_kind(kind: str, listed_only: bool = False) -> list[str]:
    return [n for n, e in TABLE.items() if e.kind == kind and (e.listed or not listed_only)]


def checkpoint_file(name: str) -> Path:
    """The shipped checkpoint file of a network (``policies/neural/checkpoints/``; it may not be there)."""
    recipe = entry(name).recipe
    if not isinstance(recipe, Checkpoint):
        raise ValueError(f"policy {name!r} is not a network; networks: {', '.join(_of_kind('learned'))}")
    return CHECKPOINT_DIR / recipe.file


def tuned_file(name: str) -> Path | None:
    """The tuned-policy file a registered name reads (a tuned file or a tuned lookahead), or None."""
    recipe = entry(name).recipe
    return _tuned.TUNED_DIR / recipe.file if isinstance(recipe, TunedFile | TunedLookahead) else None


def lookahead_base(name: str) -> str:
    """The registered policy a lookahead preset (or oracle-rollout) plans with."""
    return entry(name).recipe.base


def seed_runs() -> dict[str, tuple[str, ...]]:
    """The networks trained over seeds: method -> its training seeds' checkpoint files (:class:`Checkpoint`)."""
    return {n: e.recipe.seeds for n, e in TABLE.items() if isinstance(e.recipe, Checkpoint) and e.recipe.seeds}


def lookahead_names() -> list[str]:
    """The deployable lookahead policies (the rollout, mpc and search families), asked for by name."""
    return _of_kind("lookahead")


def _lookahead(name: str) -> Any:
    from wfbench.policies import lookahead

    recipe = entry(name).recipe
    if isinstance(recipe, TunedLookahead):
        path = _tuned.TUNED_DIR / recipe.file
        return _tuned.build(_tuned.read(path), get(recipe.base), path)
    if isinstance(recipe, MPCPreset):
        from wfbench.policies.lookahead import mpc

        return mpc.make(get(recipe.base), recipe.forecast, name=name, **mpc.PRESET_OPTIONS[recipe.option])
    if isinstance(recipe, SearchPreset) and recipe.playout:
        from wfbench.policies.lookahead import playout

        return playout.make(get(recipe.base), recipe.budget, name=name)
    if isinstance(recipe, SearchPreset):
        return lookahead.make(get(recipe.base), f"search:{recipe.budget}", name=name)
    if isinstance(recipe, SwitchPreset):  # the shipped pick first, then the method's other training seeds
        from wfbench.policies.lookahead import switch

        pick = shipped_member(recipe.base)
        members = [get(recipe.base)] + [get(s) for s in seed_members(recipe.base) if s != pick]
        return switch.SeedSwitch(members, budget=recipe.budget, name=name)
    from wfbench.policies.lookahead.rollout import SPARSE_PRESET

    if recipe.sparse == "auto":  # the sparse preset on a world as large as city only (issue #53)
        return lookahead.make(get(recipe.base), recipe.budget, name=name, sparse="auto")
    budget = f"{SPARSE_PRESET}{recipe.budget}" if recipe.sparse else recipe.budget
    return lookahead.make(get(recipe.base), budget, name=name)

# The built-ins as each table lines them up, one table read by all (issue #33): the leaderboard's seeded entries
# (wfbench.leaderboard.submit.seed_builtins), ``wfbench reproduce suite``'s policies before the networks and the
# oracle, Table 3's solver, tuned and oracle rows (S1-S4, T1-T2, O1-O2), Figure 3's solver-and-tuned group and the
# gap's methods. A lineup's members and order are what its table shows: a change here changes that table.
LINEUPS: dict[str, tuple[str, ...]] = {
    # heuristic-tuned, solver-tuned: tuned on paper-64's public seeds, entered as they are on every track;
    # oracle: shown apart, as not deployable
    "leaderboard": ("random", "heuristic", "heuristic-stochastic", "solver", "solver-dispatch", "solver-workforce",
                    "solver-positioning", "heuristic-tuned", "solver-tuned", "oracle"),
    # the composites tuned on the training split see the data the generalist networks learn from (issue #32): the
    # verdict compares a learned method with them as well as with the composites tuned on paper-64
    "suite": ("random", "heuristic", "heuristic-stochastic", "solver", "heuristic-tuned", "solver-tuned",
              "heuristic-tuned-train", "solver-tuned-train"),
    "table3-solver": ("solver", "solver-dispatch", "solver-workforce", "solver-positioning"),
    "table3-tuned": ("heuristic-tuned", "solver-tuned"),
    "table3-oracle": ("oracle-dispatch", "oracle"),
    "figure3-solver": ("solver", "heuristic-tuned", "solver-tuned"),
    "gap": ("heuristic", "solver", "oracle"),
}


# A network trained over seeds (issue #28, docs/suite.md "Learned methods over training seeds") lists its members'
# files in its Checkpoint recipe (seed_runs()); it is reported by the aggregate over them, and its own file is the
# shipped pick, a copy of one of them (the median seed, wfbench.analysis.aggregate.median_seed). Members are not
# registered names, learned_names() or oracle candidates: the oracle plays the shipped pick only.
SEED_SEP = "#seed"  # a member's spec: METHOD#seedK, METHOD#seedK@greedy
_MEMBER = re.compile(r"^(?P<method>[A-Za-z0-9_.-]+)#seed(?P<k>[^@]*)(?:@(?P<mode>.*))?$")


def member_spec(method: str, k: int) -> str:
    """The policy spec of training seed ``k`` of ``method``: ``METHOD#seedK``."""
    return f"{method}{SEED_SEP}{k}"


def seed_members(method: str) -> list[str]:
    """The specs (``METHOD#seedK``) of ``method``'s training seeds whose checkpoint file exists, in seed order.

    Empty for a policy that is not trained over seeds (:func:`seed_runs`), or whose files are not there yet.
    """
    return [member_spec(method, k) for k, f in enumerate(seed_runs().get(method, ()))
            if (CHECKPOINT_DIR / f).is_file()]


def parse_member(spec: str) -> tuple[str, int, str] | None:
    """``METHOD#seedK[@MODE]`` -> (method, k, mode), the mode ``""`` when not given; None for any other spec.

    Only the form is read (:func:`parse_spec`; a path or ``module:attr`` is never one; K not a
    number is -1): :func:`member_file` checks that the method and seed exist.
    """
    p = parse_spec(spec) if isinstance(spec, str) else None
    if p is None or p.kind != "member":
        return None
    return p.name, p.seed, p.mode or ""


def member_file(spec: str) -> Path:
    """The checkpoint file of a member spec ``METHOD#seedK[@MODE]``.

    Raises:
        ValueError: not a member spec, an unknown method, a seed it has not, or a file not there; the
            message names what is allowed.
    """
    parsed = parse_member(spec)
    if parsed is None:
        raise ValueError(f"{spec!r} is not a training seed's spec; give METHOD{SEED_SEP}K[@greedy]")
    method, k, _ = parsed
    runs = seed_runs()
    if method not in runs:
        raise ValueError(f"policy {spec!r}: {method!r} has no training seeds; methods with seeds: "
                         f"{', '.join(runs)}")
    files = runs[method]
    if not 0 <= k < len(files):
        raise ValueError(f"policy {spec!r}: {method!r} has training seeds 0-{len(files) - 1} "
                         f"({method}{SEED_SEP}0 ... {method}{SEED_SEP}{len(files) - 1}); present: "
                         f"{', '.join(seed_members(method)) or 'none yet'}")
    path = CHECKPOINT_DIR / files[k]
    if not path.is_file():
        raise ValueError(f"policy {spec!r}: its checkpoint {files[k]} is not in {CHECKPOINT_DIR.name}/ (not trained "
                         f"yet?); present: {', '.join(seed_members(method)) or 'none yet'}")
    return path


def shipped_member(method: str) -> str | None:
    """The member whose checkpoint is byte for byte the shipped pick's (:func:`checkpoint_file`), or None."""
    if method not in TABLE or TABLE[method].kind != "learned":
        return None
    shipped = checkpoint_file(method)
    if not shipped.is_file():
        return None
    data = shipped.read_bytes()
    for spec in seed_members(method):
        f = member_file(spec)
        if f.stat().st_size == len(data) and f.read_bytes() == data:
            return spec
    return None


def learned_names() -> list[str]:
    """The trained networks shipped in ``policies/neural/checkpoints/`` (only those whose file exists)."""
    return [n for n in _of_kind("learned") if (CHECKPOINT_DIR / TABLE[n].recipe.file).is_file()]


def names() -> list[str]:
    """The listed policies: the composites, the oracles, the tuned files and the shipped networks, in that order.

    The lookahead presets are registered but not listed (:func:`lookahead_names`; ``Entry.listed``).
    """
    listed = [n for kind in ("composite", "oracle", "tuned") for n in _of_kind(kind, listed_only=True)]
    return [*listed, *(n for n in learned_names() if TABLE[n].listed)]


def deployable_names() -> list[str]:
    """The listed policies that do not read the trace: composites without an oracle part, tuned files, networks.

    In the registry's order (the ``oracle``'s candidates are its reference's, :func:`oracle_candidates`).
    """
    return [n for n in names() if not TABLE[n].reads_future]


# A policy added after the oracle's numbers were published (Table 3, the suite, the gap figure) is no candidate of
# it: the oracle is the best in hindsight of a fixed, versioned list of candidates, so that adding a policy to
# wfbench does not move a published reference (docs/hindsight.md, "The oracle"). Each entry says which references
# play it (Entry.candidate_of); wfbench.policies.oracle.references holds their order.


def oracle_candidates(name: str = "oracle") -> list[str]:
    """The candidates of an oracle (or reference), in tie-breaking order, as its reference lists them.

    Its reference is a fixed tuple (:mod:`wfbench.policies.oracle.references`); a network whose
    checkpoint is not shipped is left out, as are lookaheads on it.
    """
    from wfbench.policies.oracle import references

    return references.candidates(name, _available)


def _available(name: str) -> bool:
    """Whether a candidate can be built here: a network's checkpoint, a training seed's, or a lookahead's base's."""
    member = parse_member(name)
    if member is not None:  # METHOD#seedK, a candidate from v3 on: its method shipped and its own file here
        return _available(member[0]) and name in seed_members(member[0])
    e = TABLE.get(name)
    if e is not None and e.kind == "lookahead":
        return _available(e.recipe.base)
    return e is None or e.kind != "learned" or name in learned_names()


def input_files(policy: str) -> list[Path]:
    """The files besides code whose bytes decide ``policy``'s episodes: none for a composite of built-ins.

    Its checkpoint or tuned file; a lookahead's base's too (a tuned MPC: its own and its base's
    base's; a switch: its base's training seeds' as well); a best-in-hindsight oracle's
    candidates'. What a suite piece records as its ``inputs`` (``wfbench.reproduce.provenance``)
    and what the replaying oracle checks a piece against (:mod:`wfbench.policies.oracle.pieces`).
    """
    from wfbench.policies.oracle import references

    specs = oracle_candidates(policy) if policy in references.ORACLES else [policy]
    files: list[Path] = []
    seen: set[str] = set()
    while specs:
        spec = specs.pop(0)
        if spec in seen:
            continue
        seen.add(spec)
        parsed = parse_spec(spec)
        if parsed.file is not None and parsed.file.is_file() and parsed.file not in files:
            files.append(parsed.file)
        if parsed.kind == "lookahead":
            specs.append(lookahead_base(spec))
            if isinstance(entry(spec).recipe, SwitchPreset):  # every training seed of its base plays too
                specs += seed_members(lookahead_base(spec))
    return files


def best_in_hindsight(name: str = "oracle") -> Any:
    """The ``oracle``: per seed, the best of :func:`oracle_candidates` (:mod:`wfbench.policies.oracle.best`).

    Raises:
        ValueError: networks are shipped but torch is missing. The oracle refuses rather
            than drop them, which would change its numbers under the same name.
    """
    from wfbench.policies.oracle import references

    recipe = entry(name).recipe
    if isinstance(recipe, HindsightRolloutOf):  # issue #53: not a best of candidates, the rollout on the true future
        from wfbench.policies.lookahead.rollout import AUTO_SPARSE_PAIRS, sparse_twin, spatial_twin
        from wfbench.policies.oracle.hindsight import HindsightRollout

        base = get(recipe.base)  # on city: the rollout's city preset (issue #53: else hours a seed)
        twin = sparse_twin(base)
        return HindsightRollout(base, name=name, large=(AUTO_SPARSE_PAIRS, twin, spatial_twin(twin)))
    if not isinstance(recipe, BestOf):
        raise ValueError(f"policy {name!r} is not a best-in-hindsight oracle; allowed: "
                         f"{', '.join(n for n, e in TABLE.items() if isinstance(e.recipe, BestOf))}")
    nets = [n for n in oracle_candidates(name) if parse_spec(n).kind in ("learned", "member")]
    if nets and importlib.util.find_spec("torch") is None:
        raise ValueError(f"policy {name!r} plays the shipped networks ({', '.join(nets)}) as candidates and needs "
                         "torch; install the rl extra: pip install 'wfbench[rl]' (oracle-planner needs no torch)")
    return references.make(name, get, _available, input_files)


def load_learned(path: Any, mode: str = "sample", name: str | None = None, algo: str | None = None) -> Any:
    """The policy of a trained checkpoint (:mod:`wfbench.policies.neural.policy`, imported here: torch loads now).

    ``algo`` (the prefix of ``ALGO:PATH``) must be the algorithm the checkpoint records, or
    ``ppo`` (the alias that loads any); None takes the checkpoint's own.
    """
    try:
        from wfbench.policies.neural.policy import from_checkpoint
    except ImportError as exc:
        raise ValueError(f"trained checkpoints need torch ({exc}); install the rl extra: "
                         "pip install 'wfbench[rl]'") from None
    return from_checkpoint(path, mode=mode, name=name, algo=algo)


SPEC_KINDS = ("composite", "oracle", "tuned", "learned", "member", "checkpoint", "tuned-file", "parts",
              "entry-point", "unknown", "lookahead")


@dataclass(frozen=True)
class PolicySpec:
    """A policy spec as read, once (:func:`parse_spec`): what it names, without loading or reading anything.

    ``kind`` is one of :data:`SPEC_KINDS`:

    - ``composite``, ``oracle``, ``tuned``, ``lookahead``: a registered name, the kind of its
      recipe (:class:`~wfbench.policies.table.Entry`; a tuned name's ``path`` is its shipped
      file, as is a tuned lookahead's);
    - ``learned``: a shipped network ``NAME[@MODE]`` (a :class:`~wfbench.policies.table.Checkpoint`
      entry; ``path``: its file);
    - ``member``: training seed ``seed`` of the method ``name``, ``METHOD#seedK[@MODE]``
      (:func:`seed_runs`; ``seed`` is -1 when K is not a number);
    - ``checkpoint``: ``ALGO:PATH[@MODE]`` (``algo``, ``path``);
    - ``tuned-file``: ``tuned:PATH`` or a ``.json``/``.toml`` path (``path``);
    - ``parts``: ``D+W+P``, a composite of per-decision names (``parts``);
    - ``entry-point``: ``module:attr`` (``name`` the module, ``attr``);
    - ``unknown``: none of these (``name`` without its ``@MODE``).

    ``mode`` is the text after ``@`` (``greedy``, ...), ``None`` when not given.
    """

    text: str
    kind: str
    name: str = ""
    path: str = ""
    seed: int | None = None
    mode: str | None = None
    algo: str = ""
    attr: str = ""
    parts: tuple[str, ...] = ()

    @property
    def file(self) -> Path | None:
        """The file whose bytes decide the policy (a shipped or given checkpoint or tuned file), if it names one.

        A member's is :func:`member_file`'s (which checks that it exists); the others' are not checked here.
        """
        if self.kind == "member":
            return member_file(self.text)
        return Path(self.path) if self.path else None

    @property
    def closest(self) -> list[str]:
        """For an ``unknown`` spec, the registered names closest to its name (any family), best first."""
        if self.kind != "unknown":
            return []
        return difflib.get_close_matches(self.name, list(TABLE), n=3)


def parse_spec(spec: str) -> PolicySpec:
    """The one reading of a policy spec (see :class:`PolicySpec`; :func:`get` loads what it names).

    The forms are tried in this order: a registered name, a shipped network ``NAME[@MODE]``,
    ``METHOD#seedK[@MODE]``, ``ALGO:PATH[@MODE]``, a tuned-policy file, ``D+W+P`` (no ``:``),
    ``module:attr``; anything else is ``unknown``. Nothing is checked but the form: an
    unknown name, a missing file or a wrong part is :func:`get`'s to refuse.
    """
    registered = TABLE.get(spec)
    if registered is not None and registered.kind != "learned":  # composite, oracle, tuned, lookahead
        tuned = tuned_file(spec)
        return PolicySpec(spec, registered.kind, name=spec, path="" if tuned is None else str(tuned))
    name, at, mode = spec.partition("@")  # ppo-joint@greedy, ppo:PATH@greedy
    registered = TABLE.get(name)
    if registered is not None and registered.kind == "learned":
        return PolicySpec(spec, "learned", name=name, path=str(CHECKPOINT_DIR / registered.recipe.file),
                          mode=mode if at else None)
    m = _MEMBER.match(spec)
    if m is not None:
        return PolicySpec(spec, "member", name=m["method"], seed=int(m["k"]) if m["k"].isdigit() else -1,
                          mode=m["mode"])
    algo, colon, rest = spec.partition(":")
    if colon and algo in CHECKPOINT_ALGORITHMS:
        path, at, mode = rest.rpartition("@") if "@" in rest else (rest, "", "")
        return PolicySpec(spec, "checkpoint", name=algo, algo=algo, path=path, mode=mode if at else None)
    if _tuned.is_tuned_spec(spec):  # tuned:PATH or PATH.json / PATH.toml
        return PolicySpec(spec, "tuned-file", path=str(_tuned.spec_path(spec)))
    if "+" in spec and not colon:
        return PolicySpec(spec, "parts", name=spec, parts=tuple(spec.split("+")))
    if colon:
        return PolicySpec(spec, "entry-point", name=algo, attr=rest)
    return PolicySpec(spec, "unknown", name=name, mode=mode if at else None)


def load_tuned(path: Any) -> Any:
    """The policy a tuned-policy file describes (:mod:`wfbench.policies.tuned`); ValueError names what is wrong."""
    spec = _tuned.read(path)
    return _tuned.build(spec, get(spec.base), path)


class ScenarioMismatchWarning(UserWarning):
    """A trained network evaluated on another scenario than the one its checkpoint was trained on."""


def warn_if_trained_elsewhere(policy: Any, scenario: str, stacklevel: int = 3) -> bool:
    """Warn (:class:`ScenarioMismatchWarning`) when ``policy`` was trained on another scenario than ``scenario``.

    A checkpoint's policy carries ``trained_on`` (the scenario its checkpoint records); any
    other policy has none and never warns. The evaluator calls this once per evaluation, in
    the process that started it, so the warning is neither lost in a worker nor repeated per
    chunk of seeds. ``stacklevel`` 3 points the warning at the caller of the evaluator.

    Returns:
        Whether it warned.
    """
    trained_on = getattr(policy, "trained_on", None)
    if not trained_on or trained_on == scenario:
        return False
    name = getattr(policy, "name", None) or type(policy).__qualname__
    if isinstance(trained_on, tuple):  # trained across worlds (suite ids such as paper-64-v1, or scenario names)
        if _unversioned(scenario) in {_unversioned(w) for w in trained_on}:
            return False
        warnings.warn(f"policy {name!r} was trained on scenarios {', '.join(trained_on)} and is evaluated on "
                      f"{scenario!r}, none of them: zero-shot", ScenarioMismatchWarning, stacklevel=stacklevel)
        return True
    warnings.warn(f"policy {name!r} was trained on scenario {trained_on!r} and is evaluated on {scenario!r}: "
                  "it runs, but what it learned is of another scenario", ScenarioMismatchWarning,
                  stacklevel=stacklevel)
    return True


def _unversioned(scenario: str) -> str:
    """A scenario's name without a suite version suffix (``paper-64-v1`` -> ``paper-64``)."""
    return re.sub(r"-v\d+$", "", scenario)


def get(spec: Any) -> Any:
    """A fresh policy for a registry name, a ``module:attr`` entry point, or a policy object.

    An entry point may name a policy object, a class or a factory (called with no
    arguments). ``"D+W+P"`` builds a composite from three per-decision names (for
    example ``"assignment+threshold+spatial"``; see ``DECISIONS``). A tuned-policy file
    (``path.json``, ``path.toml`` or ``tuned:path``, written by ``wfbench tune``) is its
    base policy with the tuned parameters; ``heuristic-tuned`` and ``solver-tuned`` (tuned
    on paper-64) and ``heuristic-tuned-train`` and ``solver-tuned-train`` (tuned on
    suite-v1's training split) are the files shipped in ``policies/tuned/``. ``ALGO:PATH`` is a checkpoint of ``wfbench
    train --algo ALGO`` (``ppo``, ``impala``, ``hindsight``; ``ppo:PATH`` loads any of them;
    ``ALGO:PATH@greedy`` for argmax decisions, sampled by default), and ``ppo-joint``,
    ``impala-joint``, ... the shipped ones (:func:`learned_names`). ``METHOD#seedK`` (``@greedy`` too) is
    training seed K of a method trained over seeds (:func:`seed_runs`, :func:`seed_members`). Every registered
    name is one entry of :data:`wfbench.policies.table.TABLE` (``wfbench policies`` lists them); an unknown name
    is refused with the closest registered ones.
    """
    if not isinstance(spec, str):
        if hasattr(spec, "act") and hasattr(spec, "reset"):
            return spec
        raise ValueError(f"{spec!r} is not a policy: it needs reset(seeds) and act(obs)")
    p = parse_spec(spec)
    if p.kind == "composite":
        recipe = TABLE[spec].recipe
        return Composite(recipe.dispatch, recipe.workforce, recipe.positioning, name=spec)
    if p.kind == "oracle":
        return best_in_hindsight(spec)
    if p.kind == "tuned":
        return load_tuned(Path(p.path))
    if p.kind == "lookahead":  # issue #43
        return _lookahead(spec)
    if p.kind == "learned" and p.name in learned_names():
        return load_learned(Path(p.path), p.mode or "sample", name=spec)
    if p.kind == "member":  # ppo-general#seed3, ppo-general#seed3@greedy: one training seed
        return load_learned(member_file(spec), p.mode or "sample", name=spec)
    if p.kind == "checkpoint":
        if not p.path:
            raise ValueError(f"policy {spec!r}: give a checkpoint path, e.g. {p.algo}:runs/{p.algo}/best.pt "
                             "(@greedy for argmax, @greedy-dispatch for argmax dispatch only)")
        return load_learned(p.path, "sample" if p.mode is None else p.mode, name=spec, algo=p.algo)
    if p.kind == "tuned-file":
        return load_tuned(Path(p.path))
    if p.kind == "parts":
        if len(p.parts) != 3:
            raise ValueError(f"composite {spec!r} needs three names, dispatch+workforce+positioning")
        return Composite(*p.parts, name=spec)
    if p.kind == "entry-point":
        module_name, attr = p.name, p.attr
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise ValueError(f"cannot import module {module_name!r} of policy entry point {spec!r}: {exc}") from None
        obj = module
        for part in attr.split("."):
            if not hasattr(obj, part):
                raise ValueError(f"module {module_name!r} has no attribute {attr!r} (policy entry point {spec!r})")
            obj = getattr(obj, part)
        if isinstance(obj, type) or (not (hasattr(obj, "act") and hasattr(obj, "reset")) and callable(obj)):
            obj = obj()  # a class or a factory
        if not (hasattr(obj, "act") and hasattr(obj, "reset")):
            raise ValueError(f"entry point {spec!r} is not a policy: it needs reset(seeds) and act(obs)")
        return obj
    raise ValueError(unknown_message(spec, also=", a tuned-policy file (path.json, tuned:path) or a module:attr "
                                                "entry point"))


def parts(name: str) -> tuple[str, str, str]:
    """How tables name the dispatch, workforce and positioning of the registered policy ``name``.

    The entry's own ``decisions`` when it has them (a network's say what decides, an oracle's
    are "Hindsight oracle"); else a composite's are the labels of its decisions
    (``wfbench.policies.decisions.LABELS``), a tuned file's are its base's with " (tuned)" (once), a
    lookahead's are its base's with its workforce rolled out, or planned by the MILP (mpc).
    """
    from wfbench.policies.decisions import DECISIONS, label

    e = TABLE.get(name)
    if e is None:
        raise ValueError(f"{name!r} is not a registered policy; registered: {', '.join(TABLE)}")
    recipe = e.recipe
    if e.decisions:
        return e.decisions
    if isinstance(recipe, CompositeOf):
        return tuple(label(decision, n) for decision, n in
                     zip(DECISIONS, (recipe.dispatch, recipe.workforce, recipe.positioning), strict=True))
    if isinstance(recipe, TunedFile | TunedLookahead):  # a part its base already tuned is named once
        base = _tuned.read(_tuned.TUNED_DIR / recipe.file).base if isinstance(recipe, TunedFile) else recipe.base
        return tuple(p if p.endswith(" (tuned)") else f"{p} (tuned)" for p in parts(base))
    d, w, pos = parts(recipe.base)  # issue #43: the base's parts, its workforce rolled out or planned (mpc)
    if isinstance(recipe, MPCPreset):
        how = f"{recipe.forecast}, {recipe.option}" if recipe.option else recipe.forecast
        return d, f"Staffing MILP on {how}", f"Forecast demand ({how})"
    return d, f"{w} + rollout", pos
