"""The one table of policies (wfbench.policies.table, issue #54): one typed entry per name, registered by its family.

What the registry serves is unchanged (the lists, in their order, and what every name builds); the oracles'
candidates agree with the versioned references; the budget classes are what the frontier measured; an unknown
name suggests the closest registered ones of any family; importing the registry imports no heavy module.
"""

from __future__ import annotations

import csv
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
from wfbench.policies import registry
from wfbench.policies.oracle import references
from wfbench.policies.table import (
    FAMILIES,
    KINDS,
    TABLE,
    BestOf,
    Budget,
    Checkpoint,
    CompositeOf,
    Entry,
    MPCPreset,
    RolloutPreset,
    SearchPreset,
    SwitchPreset,
    TunedFile,
    TunedLookahead,
    register,
)

from wfbench import policies

ROOT = Path(__file__).resolve().parents[2]
FRONTIER = ROOT / "docs" / "results" / "frontier-v1" / "frontier.csv"

# the lists as the nine tables gave them before issue #54, in their order (and what came after: oracle-v3 beside the
# other references, distill-general last)
NAMES = ["random", "heuristic", "heuristic-stochastic", "random-dispatch", "random-positioning", "fixed-workforce",
         "solver", "solver-dispatch", "solver-workforce", "solver-positioning", "oracle-planner", "oracle-dispatch",
         "solver-sparse", "oracle", "oracle-v2", "oracle-v3", "oracle-rollout", "heuristic-tuned", "solver-tuned",
         "heuristic-tuned-train", "solver-tuned-train", "ppo-joint", "ppo-dispatch", "impala-joint", "hindsight-joint",
         "ppo-independent", "hindsight-ppo", "ppo-general", "hindsight-general", "scalefree-general", "distill-general",
         "distill-switch-general"]
LOOKAHEADS = ["rollout-solver-tuned", "rollout-solver-tuned-1ms", "rollout-solver-tuned-100ms",
              "rollout-scalefree-general", "rollout-solver-sparse-tuned", "rollout-solver-sparse-tuned-1ms",
              "rollout-solver-sparse-tuned-100ms", "mpc-rates", "mpc-ma", "mpc-rates-calibrated", "mpc-ma-calibrated",
              "mpc-rates-backlog", "mpc-ma-backlog", "mpc-rates-tuned-train", "mpc-ma-tuned-train",
              "search-scalefree-general-1ms", "search-scalefree-general", "search-scalefree-general-100ms",
              "search-scalefree-general-playout", "switch-scalefree-general",
              "switch-scalefree-general-5ms"]


def test_the_lists_are_as_they_were_in_their_order():
    shipped = set(registry.learned_names())
    assert registry.names() == [n for n in NAMES if registry.entry(n).kind != "learned" or n in shipped]
    assert registry.lookahead_names() == LOOKAHEADS
    assert set(TABLE) == {*NAMES, *LOOKAHEADS} and len(TABLE) == len(NAMES) + len(LOOKAHEADS)
    assert registry.deployable_names() == [n for n in registry.names() if n not in
                                           ("oracle-planner", "oracle-dispatch", "oracle", "oracle-v2", "oracle-v3",
                                            "oracle-rollout")]
    assert registry.seed_runs() == {m: tuple(f"{m}-seed{i}.pt" for i in range(5))
                                    for m in ("ppo-general", "hindsight-general", "scalefree-general",
                                              "distill-general", "distill-switch-general")}


def test_each_entry_is_typed_and_its_kind_is_what_parse_spec_reads():
    for name, e in TABLE.items():
        assert e.name == name and e.family in FAMILIES and e.kind in KINDS and e.summary, name
        assert registry.parse_spec(name).kind == e.kind, name
        assert e.listed == (e.kind != "lookahead"), name  # the lookaheads are asked for by name only
        assert e.reads_future == (e.family == "oracle"), name
        assert len(registry.parts(name)) == 3 and all(registry.parts(name)), name
        assert not any("(tuned) (tuned)" in p for p in registry.parts(name)), name  # a tuned base's part once
    assert registry.parts("mpc-ma-tuned-train") == ("Assignment (tuned)", "Staffing MILP on ma (tuned)",
                                                   "Forecast demand (ma) (tuned)")
    assert [e.name for e in registry.entries("oracle") if e.kind == "composite"] == ["oracle-planner",
                                                                                     "oracle-dispatch"]


def test_lookahead_presets_are_typed_fields_not_string_prefixes():
    assert TABLE["rollout-solver-sparse-tuned-1ms"].recipe == RolloutPreset("solver-tuned", "1ms", sparse=True)
    assert TABLE["mpc-ma-calibrated"].recipe == MPCPreset("solver-tuned-train", "ma", "calibrated")
    assert TABLE["mpc-rates-tuned-train"].recipe == TunedLookahead("mpc-rates", "mpc-rates-suite-v1-train.json")
    assert TABLE["search-scalefree-general"].recipe == SearchPreset("scalefree-general", "10ms")
    from wfbench.policies.lookahead import BUDGETS, mpc, playout, search

    for e in registry.entries():
        texts = [v for v in dataclasses.asdict(e.recipe).values() if isinstance(v, str)]
        assert not any(t.startswith(("sparse:", "mpc:", "tuned:", "search:")) for t in texts), e
        if isinstance(e.recipe, RolloutPreset):
            assert e.recipe.budget in BUDGETS and e.recipe.base in TABLE, e
        if isinstance(e.recipe, SearchPreset):
            presets = playout.BUDGETS if e.recipe.playout else search.BUDGETS
            assert e.recipe.budget in presets and e.recipe.base in TABLE, e
        if isinstance(e.recipe, MPCPreset):
            assert e.recipe.forecast in mpc.FORECASTS and set(MPCPreset.OPTIONS) == set(mpc.PRESET_OPTIONS), e
        if isinstance(e.recipe, TunedLookahead | TunedFile):
            assert registry.tuned_file(e.name).is_file(), e


def test_bad_entries_are_refused_in_one_line():
    with pytest.raises(ValueError, match=r"^mpc preset option 'calibrate' is not allowed; allowed: '', "
                                         r"'calibrated', 'backlog'$"):
        MPCPreset("solver-tuned-train", "ma", "calibrate")
    with pytest.raises(ValueError, match=r"^policy 'x': family 'lookahead' is not allowed; allowed: composite, "
                                         r"tuned, learned, rollout, mpc, search, oracle$"):
        Entry("x", "lookahead", RolloutPreset("solver-tuned", "1ms"), "x")
    with pytest.raises(ValueError, match=r"^policy 'heuristic' is already registered \(family composite\)"):
        register(Entry("heuristic", "composite", CompositeOf("random", "random", "random"), "another"))
    register(TABLE["heuristic"])  # the same entry again (a module imported twice) is no change
    with pytest.raises(ValueError, match=r"^policy 'net': a Checkpoint has no decisions to take its labels from; "
                                         r"allowed: three labels \(dispatch, workforce, positioning\)$"):
        Entry("net", "learned", Checkpoint("net.pt"), "a network")
    with pytest.raises(ValueError, match=r"^unknown policy family 'mcp'; allowed: composite, tuned, learned, "
                                         r"rollout, mpc, search, oracle$"):
        registry.entries("mcp")


def test_every_name_builds_its_recipe_under_its_name():
    from wfbench.policies.composite import Composite
    from wfbench.policies.lookahead import MPC, NetworkRollout, NetworkSearch, Rollout, SeedSwitch
    from wfbench.policies.oracle import BestInHindsight
    from wfbench.policies.oracle.hindsight import HindsightRollout

    shipped = set(registry.learned_names())
    for e in registry.entries():
        base = getattr(e.recipe, "base", None)
        if e.kind == "learned" and e.name not in shipped or base in TABLE and TABLE[base].kind == "learned" and \
                base not in shipped:
            continue
        p = policies.get(e.name)
        assert p.name == e.name, e.name
        expected = {CompositeOf: Composite, BestOf: BestInHindsight, MPCPreset: MPC, SearchPreset: NetworkSearch,
                    TunedLookahead: MPC, SwitchPreset: SeedSwitch}.get(type(e.recipe))
        if isinstance(e.recipe, RolloutPreset):
            expected = NetworkRollout if TABLE[e.recipe.base].kind == "learned" else Rollout
            assert expected is NetworkRollout or p.sparse_knob == e.recipe.sparse, e.name
        if type(e.recipe).__name__ == "HindsightRolloutOf":
            expected = HindsightRollout
        if expected is not None:
            assert isinstance(p, expected), (e.name, type(p))
        if isinstance(e.recipe, MPCPreset):
            assert (p.calibrate, p.backlog) == \
                {"": (False, False), "calibrated": (True, False), "backlog": (True, True)}[e.recipe.option], e.name
        if isinstance(e.recipe, BestOf):
            assert list(p.candidates) == registry.oracle_candidates(e.name), e.name


def test_the_oracle_candidates_of_each_entry_are_its_references_lists():
    for ref, listed in references.REFERENCES.items():
        # an entry says which references play it; a training seed (no entry) is listed with its method
        members = [registry.parse_member(n) for n in listed if registry.parse_member(n)]
        assert {n for n, e in TABLE.items() if ref in e.candidate_of} == {n for n in listed if n in TABLE}, ref
        assert len(members) + len({n for n in listed if n in TABLE}) == len(listed), ref
        assert all(method in listed and not mode for method, _, mode in members), ref
    assert {n: e.recipe.reference for n, e in TABLE.items() if isinstance(e.recipe, BestOf)} == references.ORACLES
    for name, ref in references.ORACLES.items():
        assert registry.oracle_candidates(name) == [n for n in references.REFERENCES[ref] if registry._available(n)]
    assert TABLE["mpc-ma-backlog"].candidate_of == ("v3",) and TABLE["mpc-ma"].candidate_of == ("v2", "v3")
    assert not TABLE["search-scalefree-general-playout"].oracle_candidate


def test_the_budget_classes_are_what_the_frontier_measured():
    with FRONTIER.open() as f:
        measured = {r["policy"]: float(r["cpu_ms_per_step"]) for r in csv.DictReader(f)}
    assert measured, FRONTIER
    for name, e in TABLE.items():
        expected = Budget.of(measured[name]) if name in measured else None
        assert e.budget == expected, (name, e.budget, measured.get(name))
        assert e.budget_class == ("not measured" if expected is None else expected.value)
    assert [Budget.of(x) for x in (0.0, 1.0, 1.5, 10.0, 99.0, 100.5)] == \
        [Budget.MS_1, Budget.MS_1, Budget.MS_10, Budget.MS_10, Budget.MS_100, Budget.MORE]


@pytest.mark.parametrize(("spec", "closest"), [
    ("rollout-solver-tund", "'rollout-solver-tuned'"),  # a lookahead, not listed by names()
    ("orcale-v2", "'oracle-v2'"),
    ("mpc-rate", "'mpc-rates'"),
    ("heuristc", "'heuristic'"),
])
def test_an_unknown_name_suggests_the_closest_of_every_family(spec, closest):
    with pytest.raises(ValueError) as info:
        policies.get(spec)
    message = str(info.value)
    assert message.startswith(f"unknown policy {spec!r}; available: random, heuristic, ") and "\n" not in message
    assert f"; did you mean {closest}" in message and message.count("did you mean") == 1
    assert "oracle-rollout" in message and "search-scalefree-general-100ms" in message
    assert registry.parse_spec(spec).kind == "unknown" and closest.strip("'") in registry.parse_spec(spec).closest


def test_an_unregistered_name_has_no_entry_and_no_suggestion_when_none_is_close():
    with pytest.raises(ValueError, match=r"^unknown registered policy 'zzzz'; available: random, heuristic, [^;]*"
                                         r", oracle-dispatch$"):
        registry.entry("zzzz")
    assert registry.parse_spec("zzzz").closest == [] and registry.parse_spec("heuristic").closest == []


def test_importing_the_registry_imports_nothing_heavy():
    heavy = ("torch", "highspy", "wfbench.policies.lookahead.rollout", "wfbench.policies.lookahead.mpc",
             "wfbench.policies.lookahead.search", "wfbench.policies.lookahead.network_rollout",
             "wfbench.policies.neural.policy")
    code = (f"import sys, wfbench.policies.registry as r; assert len(r.TABLE) == {len(TABLE)}; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and run.stdout.strip() == "[]", run.stdout + run.stderr
