"""Policies by name: built-in composites, ``"D+W+P"`` composites of built-in decisions, tuned-policy files.

And ``module:attr`` entry points.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wfbench.policies import tuned as _tuned
from wfbench.policies.composite import Composite
from wfbench.policies.neural import CHECKPOINT_ALGORITHMS

from wfbench.core.paths import CHECKPOINTS, data_path

# name -> (dispatch, workforce, positioning, description)
COMPOSITES: dict[str, tuple[str, str, str, str]] = {
    "random": ("random", "random", "random", "uniformly random valid actions for all three decisions (Table 3 row 1)"),
    "heuristic": ("nearest", "threshold", "spatial", "the paper's deterministic heuristics (Table 3 row 4)"),
    "heuristic-stochastic": (
        "inverse-distance", "threshold-epsilon", "spatial-gaussian", "the stochastic variants of the heuristics",
    ),
    "random-dispatch": (
        "random", "threshold", "spatial", "random dispatch, heuristic workforce and positioning (row 2)",
    ),
    "random-positioning": (
        "nearest", "threshold", "random", "heuristic dispatch and workforce, random positioning (row 3)",
    ),
    "fixed-workforce": ("nearest", "fixed", "none", "nearest dispatch, no hiring or letting go (Table 2)"),
    "solver": ("assignment", "staffing", "facility-location", "the three solver-backed decisions (docs/solvers.md)"),
    "solver-dispatch": (
        "assignment", "threshold", "spatial", "optimal-assignment dispatch, heuristic workforce and positioning",
    ),
    "solver-workforce": ("nearest", "staffing", "spatial", "square-root staffing, heuristic dispatch and positioning"),
    "solver-positioning": (
        "nearest", "threshold", "facility-location", "p-median positioning, heuristic dispatch and workforce",
    ),
    "oracle-planner": (
        "oracle", "oracle", "oracle", "the hindsight planner for all three decisions: reads the trace, not "
        "deployable (docs/hindsight.md)",
    ),
    "oracle-dispatch": (
        "oracle", "threshold", "spatial", "hindsight dispatch, heuristic workforce and positioning: not deployable",
    ),
    # added after the published tables: opt-in, not an oracle candidate (NOT_ORACLE_CANDIDATES)
    "solver-sparse": (
        "assignment-sparse", "staffing", "facility-location-sparse", "the solver composite with its assignment and "
        "p-median solved on sparse candidate graphs (the k nearest; docs/solvers.md, \"Sparse candidate graphs\")",
    ),
}

# name -> description: oracles that are not composites (docs/hindsight.md, "The oracle")
ORACLES: dict[str, str] = {
    "oracle": "per seed, the best in hindsight of oracle-planner and every deployable built-in (the composites, the "
              "tuned files and the shipped networks): reads the trace, not deployable (docs/hindsight.md)",
    # issue #53: the references are versioned (wfbench.policies.oracle.references; docs/hindsight.md)
    "oracle-v2": "reference v2: per seed, the best in hindsight of every deployable family, the lookaheads "
                 "included, and oracle-rollout; replays recorded episodes and committed pieces (docs/hindsight.md)",
    "oracle-rollout": "the rollout of solver-tuned on the true future, rolled to the end of the episode: reads the "
                      "trace, not deployable (docs/hindsight.md, \"The hindsight rollout\")",
}

# name -> (file under policies/tuned/, description): tuned-policy files shipped with wfbench (docs/policies.md, Tuning)
TUNED: dict[str, tuple[str, str]] = {
    "heuristic-tuned": ("heuristic-paper-64.json", "the heuristic composite tuned on paper-64's public seeds "
                        "(wfbench tune)"),
    "solver-tuned": ("solver-paper-64.json", "the solver composite tuned jointly on paper-64's public seeds "
                     "(wfbench tune)"),
    "heuristic-tuned-train": ("heuristic-suite-v1-train.json", "the heuristic composite tuned on suite-v1's "
                              "training split: the mean normalized score over its eight scenarios' public seeds "
                              "(wfbench tune --scenarios suite-v1:train)"),
    "solver-tuned-train": ("solver-suite-v1-train.json", "the solver composite tuned jointly on suite-v1's training "
                           "split: the mean normalized score over its eight scenarios' public seeds (wfbench tune "
                           "--scenarios suite-v1:train)"),
}


# -- deployable lookahead (issue #43) ---------------------------------------------------------------------------------
# name -> (base, budget preset, description): a rollout of a compiled base on K sampled futures of H steps, one name
# per budget preset (wfbench.policies.lookahead, docs/policies.md "Lookahead policies"). Asked for by name (get,
# parse_spec); not yet in names(), deployable_names() or the oracle's candidates: entering those runs them in every
# table, the identity check and the leaderboard's seeding, which issue #43 does with the frontier
LOOKAHEAD: dict[str, tuple[str, str, str]] = {
    "rollout-solver-tuned": ("solver-tuned", "10ms", "rollout of solver-tuned on sampled futures (K=4, H=80, R=20)"),
    "rollout-solver-tuned-1ms": ("solver-tuned", "1ms", "rollout of solver-tuned, the 1 ms budget (K=2, H=80, "
                                 "R=80)"),
    "rollout-solver-tuned-100ms": ("solver-tuned", "100ms", "rollout of solver-tuned, the 100 ms budget (K=16, "
                                   "H=120, R=10)"),
    # the network as the base: the same knobs as the 1 ms preset cost far more (H forward passes a decision)
    "rollout-scalefree-general": ("scalefree-general", "1ms", "rollout of the scale-free network on sampled "
                                  "futures, the network playing them (K=2, H=80, R=80)"),
}

# for city (issue #53): a preset field "sparse:BUDGET" is BUDGET's knobs on solver-tuned's sparse twin (its tuned
# parameters, assignment and p-median on the k nearest), a decision every R steps only, the futures positioned by
# spatial averaging (wfbench.policies.lookahead.rollout.SPARSE_PRESET; docs/policies.md, "Lookahead policies on city")
LOOKAHEAD.update({
    "rollout-solver-sparse-tuned": ("solver-tuned", "sparse:10ms", "rollout of solver-tuned's sparse twin, for "
                                    "city: K=4, H=80, a decision every R=20 steps, spatial positioning in the futures"),
    "rollout-solver-sparse-tuned-1ms": ("solver-tuned", "sparse:1ms", "rollout-solver-sparse-tuned at the 1 ms "
                                        "budget (K=2, H=80, R=80)"),
    "rollout-solver-sparse-tuned-100ms": ("solver-tuned", "sparse:100ms", "rollout-solver-sparse-tuned at the "
                                          "100 ms budget (K=16, H=120, R=10)"),
})


# the rolling-horizon MILP (issue #43): a preset field naming the forecast kind, "mpc:rates" or "mpc:ma"; the base
# plays dispatch (its assignment), the MILP staffs and positions on the forecast (docs/policies.md, "mpc")
LOOKAHEAD.update({
    "mpc-rates": ("solver-tuned-train", "mpc:rates", "rolling-horizon staffing MILP (HiGHS) on the public rates and "
                  "schedules, H=100, re-solved every R=20 steps; assignment dispatch"),
    "mpc-ma": ("solver-tuned-train", "mpc:ma", "rolling-horizon staffing MILP (HiGHS) on a 100-step moving average "
               "of observed requests (no demand model), H=100, R=20; assignment dispatch"),
})
# the same with its capacity measured from observed repairs (issue #53; docs/policies.md, "Why it churns"): a
# preset field "mpc:FORECAST:calibrated" turns on MPC(calibrate=True)
LOOKAHEAD.update({
    "mpc-rates-calibrated": ("solver-tuned-train", "mpc:rates:calibrated", "mpc-rates with the capacity per person "
                             "measured from observed repairs and the working share averaged over the window"),
    "mpc-ma-calibrated": ("solver-tuned-train", "mpc:ma:calibrated", "mpc-ma with the capacity per person measured "
                          "from observed repairs; the base staffs until a window of requests is seen"),
})
# calibrated, with a fluid queue of repair requests in the MILP (issue #53's second design; docs/policies.md, "The
# second design"): a preset field "mpc:FORECAST:backlog" turns on MPC(calibrate=True, backlog=True)
LOOKAHEAD.update({
    "mpc-rates-backlog": ("solver-tuned-train", "mpc:rates:backlog", "mpc-rates-calibrated whose MILP carries the "
                          "repair backlog (a fluid queue seeded from the waiting requests, priced as downtime)"),
    "mpc-ma-backlog": ("solver-tuned-train", "mpc:ma:backlog", "mpc-ma-calibrated whose MILP carries the repair "
                       "backlog (a fluid queue seeded from the waiting requests, priced as downtime)"),
})


# tuned on suite-v1's training split, public seeds 1000-1004 (issue #43; docs/policies.md, "mpc"): a preset field
# "tuned:FILE" names the tuned-policy file under policies/tuned/, whose base is the untuned lookahead
LOOKAHEAD.update({
    "mpc-rates-tuned-train": ("mpc-rates", "tuned:mpc-rates-suite-v1-train.json", "mpc-rates with its knobs, prices "
                              "and capacity scale tuned on suite-v1's training split (wfbench tune)"),
    "mpc-ma-tuned-train": ("mpc-ma", "tuned:mpc-ma-suite-v1-train.json", "mpc-ma with its knobs, prices and "
                           "capacity scale tuned on suite-v1's training split (wfbench tune)"),
})


# search with the network (issue #52; docs/policies.md, "search-scalefree-general"): a preset field "search:BUDGET"
# names a preset of wfbench.policies.lookahead.search (greedy futures ended at the network's value, a noise test)
LOOKAHEAD.update({
    "search-scalefree-general-1ms": ("scalefree-general", "search:1ms", "search with the scale-free network, the "
                                     "1 ms budget (K=2, H=10, R=80, top=2, z=1)"),
    "search-scalefree-general": ("scalefree-general", "search:10ms", "search with the scale-free network: greedy "
                                 "futures ended at its value, a noise test (K=8, H=20, R=20, top=3, z=1)"),
    "search-scalefree-general-100ms": ("scalefree-general", "search:100ms", "search with the scale-free network, "
                                       "the 100 ms budget (K=32, H=20, R=10, top=4, z=1)"),
})


def _lookahead_file(name: str) -> Path | None:
    """The tuned-policy file a tuned lookahead reads, or None."""
    preset = LOOKAHEAD[name][1]
    return _tuned.TUNED_DIR / preset[6:] if preset.startswith("tuned:") else None


def lookahead_names() -> list[str]:
    """The deployable lookahead policies (:data:`LOOKAHEAD`), asked for by name."""
    return list(LOOKAHEAD)


def _lookahead(name: str) -> Any:
    from wfbench.policies.lookahead import make

    base, preset, _ = LOOKAHEAD[name]
    if preset.startswith("tuned:"):
        path = _lookahead_file(name)
        return _tuned.build(_tuned.read(path), get(base), path)
    if preset.startswith("mpc:"):
        from wfbench.policies.lookahead import mpc

        forecast, _, option = preset[4:].partition(":")
        return mpc.make(get(base), forecast, name=name, **mpc.PRESET_OPTIONS[option])
    return make(get(base), preset, name=name)
# -- end of deployable lookahead --------------------------------------------------------------------------------------

# name -> (checkpoint under policies/neural/checkpoints/, description): trained networks (docs/rl.md), each
# named by the algorithm that trained it (its checkpoint's algo key: no key is ppo); a name is offered only when
# its file is there, and loading it needs torch (the rl extra)
LEARNED: dict[str, tuple[str, str]] = {
    "ppo-joint": ("ppo-joint-paper-64.pt", "the joint PPO network (all three decisions) trained on paper-64"),
    "ppo-dispatch": ("ppo-dispatch-paper-64.pt", "the dispatch-only PPO network trained on paper-64, heuristic "
                     "workforce and positioning"),
    "impala-joint": ("impala-joint-paper-64.pt", "the joint network trained with IMPALA (V-trace) on paper-64"),
    "hindsight-joint": ("hindsight-joint-paper-64.pt", "the joint network trained by imitating the hindsight "
                        "oracles (DAgger) on paper-64"),
    "ppo-independent": ("ppo-independent-paper-64.pt", "three PPO networks, one per decision (independent "
                        "agents), trained together on paper-64"),
    "hindsight-ppo": ("hindsight-ppo-paper-64.pt", "ppo-joint with its workforce head improved by hindsight "
                      "learning on its own action values (the known future, its own policy acting) on paper-64"),
    "ppo-general": ("ppo-general.pt", "the joint PPO network trained across suite-v1's eight training scenarios "
                    "(from ppo-joint's weights); the median of 5 training seeds (ppo-general#seedK)"),
    "hindsight-general": ("hindsight-general.pt", "ppo-general with its workforce head improved by hindsight "
                          "learning on its own action values across the training scenarios; the median of 5 seeds"),
    "scalefree-general": ("scalefree-general.pt", "the scale-free network (observation version 2: lengths in "
                          "travel time, the world's parameters as context) trained by PPO from scratch across "
                          "suite-v1's eight training scenarios; the median of 5 training seeds"),
}
CHECKPOINT_DIR = data_path(CHECKPOINTS)  # policies/neural/checkpoints/ (wfbench/policies/... in a wheel)

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


# method -> the checkpoint files (under CHECKPOINT_DIR) of its training seeds: the same training command with only
# the seed varied (issue #28, docs/suite.md "Learned methods over training seeds"). A method is reported by the
# aggregate over these members; its LEARNED entry is the shipped pick, a copy of the file of one of them (the seed
# whose mean score on the public seeds of the training scenarios is the median, wfbench.analysis.aggregate.median_seed).
# Members are not in LEARNED, learned_names() or oracle_candidates(): the oracle plays the shipped pick only.
SEED_RUNS: dict[str, tuple[str, ...]] = {
    "ppo-general": tuple(f"ppo-general-seed{i}.pt" for i in range(5)),
    "hindsight-general": tuple(f"hindsight-general-seed{i}.pt" for i in range(5)),
    "scalefree-general": tuple(f"scalefree-general-seed{i}.pt" for i in range(5)),
}
SEED_SEP = "#seed"  # a member's spec: METHOD#seedK, METHOD#seedK@greedy
_MEMBER = re.compile(r"^(?P<method>[A-Za-z0-9_.-]+)#seed(?P<k>[^@]*)(?:@(?P<mode>.*))?$")


def member_spec(method: str, k: int) -> str:
    """The policy spec of training seed ``k`` of ``method``: ``METHOD#seedK``."""
    return f"{method}{SEED_SEP}{k}"


def seed_members(method: str) -> list[str]:
    """The specs (``METHOD#seedK``) of ``method``'s training seeds whose checkpoint file exists, in seed order.

    Empty for a policy that is not in :data:`SEED_RUNS` (or whose files are not there yet).
    """
    return [member_spec(method, k) for k, f in enumerate(SEED_RUNS.get(method, ()))
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
    if method not in SEED_RUNS:
        raise ValueError(f"policy {spec!r}: {method!r} has no training seeds; methods with seeds: "
                         f"{', '.join(SEED_RUNS)}")
    files = SEED_RUNS[method]
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
    """The member whose checkpoint is byte for byte the shipped pick's (``LEARNED[method]``'s file), or None."""
    if method not in LEARNED:
        return None
    shipped = CHECKPOINT_DIR / LEARNED[method][0]
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
    return [n for n, (f, _) in LEARNED.items() if (CHECKPOINT_DIR / f).is_file()]


def names() -> list[str]:
    return [*COMPOSITES, *ORACLES, *TUNED, *learned_names()]


def deployable_names() -> list[str]:
    """The registered policies that do not read the trace: composites without an oracle part, tuned files, networks.

    In the registry's order, which is the order in which the ``oracle`` breaks ties.
    """
    return [*_deployable_composites(), *TUNED, *learned_names()]


def _deployable_composites() -> list[str]:
    return [n for n, (d, w, p, _) in COMPOSITES.items() if "oracle" not in (d, w, p)]


# Policies added after the oracle's numbers were published (Table 3, the suite, the gap figure) that it does not
# play: the oracle is the best in hindsight of a fixed set of candidates, so that adding a policy to wfbench does
# not move a published reference (docs/hindsight.md, "The oracle"). They are compared with it, not inside it.
NOT_ORACLE_CANDIDATES = frozenset({"heuristic-tuned-train", "solver-tuned-train", "scalefree-general", "solver-sparse"})


def oracle_candidates(name: str = "oracle") -> list[str]:
    """The candidates of an oracle (or reference), in tie-breaking order, as its reference lists them.

    Its reference is a fixed tuple (:mod:`wfbench.policies.oracle.references`); a network whose
    checkpoint is not shipped is left out, as are lookaheads on it.
    """
    from wfbench.policies.oracle import references

    return references.candidates(name, _available)


def _available(name: str) -> bool:
    """Whether a candidate can be built here: a network's checkpoint, or a lookahead's base's, is shipped."""
    if name in LOOKAHEAD:
        return _available(LOOKAHEAD[name][0])
    return name not in LEARNED or name in learned_names()


def best_in_hindsight(name: str = "oracle") -> Any:
    """The ``oracle``: per seed, the best of :func:`oracle_candidates` (:mod:`wfbench.policies.oracle.best`).

    Raises:
        ValueError: networks are shipped but torch is missing. The oracle refuses rather
            than drop them, which would change its numbers under the same name.
    """
    from wfbench.policies.oracle import references

    if name == "oracle-rollout":  # issue #53: not a best of candidates, the rollout on the true future
        from wfbench.policies.oracle.hindsight import HindsightRollout

        return HindsightRollout(get("solver-tuned"), name=name)
    nets = [n for n in oracle_candidates(name) if n in LEARNED]
    if nets and importlib.util.find_spec("torch") is None:
        raise ValueError(f"policy {name!r} plays the shipped networks ({', '.join(nets)}) as candidates and needs "
                         "torch; install the rl extra: pip install 'wfbench[rl]' (oracle-planner needs no torch)")
    return references.make(name, get, _available)


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

    - ``composite``, ``oracle``, ``tuned``: a registered name (:data:`COMPOSITES`,
      :data:`ORACLES`, :data:`TUNED`; a tuned name's ``path`` is its shipped file);
    - ``learned``: a shipped network ``NAME[@MODE]`` (:data:`LEARNED`; ``path``: its file);
    - ``member``: training seed ``seed`` of the method ``name``, ``METHOD#seedK[@MODE]``
      (:data:`SEED_RUNS`; ``seed`` is -1 when K is not a number);
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


def parse_spec(spec: str) -> PolicySpec:
    """The one reading of a policy spec (see :class:`PolicySpec`; :func:`get` loads what it names).

    The forms are tried in this order: a registered name, a shipped network ``NAME[@MODE]``,
    ``METHOD#seedK[@MODE]``, ``ALGO:PATH[@MODE]``, a tuned-policy file, ``D+W+P`` (no ``:``),
    ``module:attr``; anything else is ``unknown``. Nothing is checked but the form: an
    unknown name, a missing file or a wrong part is :func:`get`'s to refuse.
    """
    if spec in COMPOSITES:
        return PolicySpec(spec, "composite", name=spec)
    if spec in ORACLES:
        return PolicySpec(spec, "oracle", name=spec)
    if spec in TUNED:
        return PolicySpec(spec, "tuned", name=spec, path=str(_tuned.TUNED_DIR / TUNED[spec][0]))
    if spec in LOOKAHEAD:  # issue #43
        tuned = _lookahead_file(spec)
        return PolicySpec(spec, "lookahead", name=spec, path="" if tuned is None else str(tuned))
    name, at, mode = spec.partition("@")  # ppo-joint@greedy, ppo:PATH@greedy
    if name in LEARNED:
        return PolicySpec(spec, "learned", name=name, path=str(CHECKPOINT_DIR / LEARNED[name][0]),
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
    ``impala-joint``, ... the shipped ones (``LEARNED``). ``METHOD#seedK`` (``@greedy`` too) is
    training seed K of a method of :data:`SEED_RUNS` (:func:`seed_members`).
    """
    if not isinstance(spec, str):
        if hasattr(spec, "act") and hasattr(spec, "reset"):
            return spec
        raise ValueError(f"{spec!r} is not a policy: it needs reset(seeds) and act(obs)")
    p = parse_spec(spec)
    if p.kind == "composite":
        d, w, pos, _ = COMPOSITES[spec]
        return Composite(d, w, pos, name=spec)
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
    raise ValueError(f"unknown policy {spec!r}; available: {', '.join(names())}, a tuned-policy file "
                     "(path.json, tuned:path) or a module:attr entry point")


# name -> the labels of its dispatch, workforce and positioning in tables (Table 3): a network has no decision
# names to take them from, so each says what decides (PPO, hindsight learning, or both)
LEARNED_PARTS: dict[str, tuple[str, str, str]] = {
    "ppo-joint": ("PPO", "PPO", "PPO"),
    "ppo-dispatch": ("PPO", "Heuristic", "Heuristic"),
    "impala-joint": ("IMPALA", "IMPALA", "IMPALA"),
    "hindsight-joint": ("Hindsight learning", "Hindsight learning", "Hindsight learning"),
    "ppo-independent": ("PPO (own net)", "PPO (own net)", "PPO (own net)"),
    "hindsight-ppo": ("PPO", "PPO + hindsight learning", "PPO"),
    "ppo-general": ("PPO (generalist)", "PPO (generalist)", "PPO (generalist)"),
    "hindsight-general": ("PPO (generalist)", "PPO + hindsight learning (generalist)", "PPO (generalist)"),
    "scalefree-general": ("PPO (scale-free)", "PPO (scale-free)", "PPO (scale-free)"),
}


def parts(name: str) -> tuple[str, str, str]:
    """How tables name the dispatch, workforce and positioning of the registered policy ``name``.

    A composite's parts are the labels of its decisions (``wfbench.policies.decisions.LABELS``), a
    tuned file's are its base's with " (tuned)", a network's are in :data:`LEARNED_PARTS`.
    """
    from wfbench.policies.decisions import DECISIONS, label

    if name in COMPOSITES:
        return tuple(label(decision, n) for decision, n in zip(DECISIONS, COMPOSITES[name][:3], strict=True))
    if name in ORACLES:
        return ("Hindsight oracle",) * 3
    if name in TUNED:
        base = _tuned.read(_tuned.TUNED_DIR / TUNED[name][0]).base
        return tuple(f"{p} (tuned)" for p in parts(base))
    if name in LEARNED_PARTS:
        return LEARNED_PARTS[name]
    if name in LOOKAHEAD and LOOKAHEAD[name][1].startswith("tuned:"):
        return tuple(f"{p} (tuned)" for p in parts(LOOKAHEAD[name][0]))
    if name in LOOKAHEAD:  # issue #43: the base's parts, its workforce rolled out or planned (mpc)
        d, w, pos = parts(LOOKAHEAD[name][0])
        if LOOKAHEAD[name][1].startswith("mpc:"):
            forecast, _, option = LOOKAHEAD[name][1][4:].partition(":")
            how = f"{forecast}, {option}" if option else forecast
            return d, f"Staffing MILP on {how}", f"Forecast demand ({how})"
        return d, f"{w} + rollout", pos
    registered = [*COMPOSITES, *ORACLES, *TUNED, *LEARNED]
    raise ValueError(f"{name!r} is not a registered policy; registered: {', '.join(registered)}")
