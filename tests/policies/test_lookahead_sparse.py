"""The rollout for city (issue #53, item 1): the sparse twin, decisions every R steps, cheaper futures.

Public seeds only (1000-1049). Costs are measured by ``benchmarks/lookahead_city.py``, never here.
"""

import numpy as np
import pytest
from wfbench.policies.episode import play_episodes
from wfbench.policies.lookahead import BUDGETS, Rollout
from wfbench.policies.lookahead.rollout import sparse_twin, spatial_twin

from wfbench import ScenarioConfig, Simulator, policies

SMALL = ScenarioConfig.preset("small").replace(horizon=120)
SEEDS = [1000, 1001, 1002]
SPARSE_PRESETS = ("rollout-solver-sparse-tuned", "rollout-solver-sparse-tuned-1ms", "rollout-solver-sparse-tuned-100ms")


def nsw_of(composite, config, seeds):
    """Whole episodes of a compiled composite (the compiled rollout, no lookahead)."""
    sim = Simulator(config, seeds, threads=1)
    codes, hp, pstate = composite.compiled_plan(seeds, sim.M, sim.N)
    play_episodes(sim, codes, hp, pstate, threads=1)
    return sim.episode_means()["nsw"]


def play(pol, config, seeds, steps=None):
    sim = Simulator(config, seeds)
    obs = sim.reset()
    pol.reset(seeds)
    acted, decided = [], []
    while not sim.done and (steps is None or len(acted) < steps):
        before = pol.timing.get("decisions", 0.0)
        a = pol.act(obs)
        acted.append({k: v.copy() for k, v in a.items()})
        decided.append(pol.timing["decisions"] > before)
        sim.step(a)
        obs = sim.observe()
    return sim.episode_means()["nsw"], acted, np.array(decided)


def test_the_sparse_twin_keeps_the_tuned_parameters_and_of_solver_is_solver_sparse():
    tuned = policies.get("solver-tuned")
    twin = sparse_twin(tuned)
    assert [p.name for p in twin.parts.values()] == ["assignment-sparse", "staffing", "facility-location-sparse"]
    assert twin.params() == tuned.params() and twin.compiled
    assert np.array_equal(nsw_of(sparse_twin(policies.get("solver")), SMALL, SEEDS),
                          nsw_of(policies.get("solver-sparse"), SMALL, SEEDS))
    assert sparse_twin(policies.get("solver-sparse")).params() == policies.get("solver-sparse").params()
    spatial = spatial_twin(twin)
    assert [p.name for p in spatial.parts.values()] == ["assignment-sparse", "staffing", "spatial"]
    assert spatial.params()["positioning.smoothing"] == tuned.params()["positioning.smoothing"]


@pytest.mark.parametrize("name", SPARSE_PRESETS)
def test_the_city_presets_play_the_sparse_twin_and_decide_every_r_steps(name):
    pol = policies.get(name)
    preset = name.removeprefix("rollout-solver-sparse-tuned").lstrip("-") or "10ms"
    assert pol.settings() == dict(zip("KHR", BUDGETS[preset], strict=True))
    assert [p.name for p in pol.base.parts.values()] == ["assignment-sparse", "staffing", "facility-location-sparse"]
    assert pol.base.params() == policies.get("solver-tuned").params()
    assert [p.name for p in pol.futures.parts.values()] == ["assignment-sparse", "staffing", "spatial"]
    assert pol.decide == "period"


def test_decide_period_rolls_out_only_every_r_steps_and_base_also_where_the_base_hires():
    kw = {"K": 1, "H": 10, "R": 15, "scenario": SMALL}
    _, _, period = play(Rollout(policies.get("solver-tuned"), decide="period", **kw), SMALL, [1001], steps=90)
    _, _, base = play(Rollout(policies.get("solver-tuned"), **kw), SMALL, [1001], steps=90)
    assert np.array_equal(np.flatnonzero(period), np.arange(0, 90, 15))
    assert base.sum() > period.sum() and base[period].all()


def test_the_futures_are_played_by_the_futures_composite():
    kw = {"K": 2, "H": 20, "R": 10, "scenario": SMALL}
    tuned = policies.get("solver-tuned")
    plain = Rollout(tuned, **kw)
    same = Rollout(tuned, futures=policies.get("solver-tuned"), **kw)
    other = Rollout(tuned, futures=policies.get("random"), **kw)
    for pol in (plain, same, other):
        pol.reset([1002])
    obs = Simulator(SMALL, [1002]).reset()
    for pol in (plain, same, other):
        pol.act(obs)
    assert np.array_equal(plain.last_scores, same.last_scores, equal_nan=True)  # the base as futures: the same
    assert not np.array_equal(plain.last_scores, other.last_scores, equal_nan=True)  # random futures score otherwise


def test_a_sparse_preset_is_not_worse_than_its_base_on_small_public_seeds():
    twin = sparse_twin(policies.get("solver-tuned"))
    base = nsw_of(twin, SMALL, SEEDS)
    mine, _, decided = play(Rollout(policies.get("solver-tuned"), budget="sparse:10ms", scenario=SMALL), SMALL,
                            SEEDS)
    assert decided.sum() == len(range(0, SMALL.horizon, 20))
    assert mine.mean() >= base.mean() - 0.005, (mine, base)


@pytest.mark.parametrize("kwargs, says", [
    ({"sparse": "yes"}, "rollout knob sparse = 'yes' is not allowed; allowed: True or False"),
    ({"sparse": 1}, "rollout knob sparse = 1 is not allowed; allowed: True or False"),
    ({"decide": "sometimes"}, "rollout knob decide = 'sometimes' is not allowed; allowed: base ("),
    ({"budget": "sparse:2ms"}, "rollout budget '2ms' is not allowed; allowed: 1ms, 10ms, 100ms"),
    ({"futures": "heuristic"}, "rollout futures 'heuristic' is not a composite of built-in kernels"),
])
def test_bad_city_knobs_get_one_line(kwargs, says):
    with pytest.raises(ValueError) as err:
        Rollout(policies.get("solver-tuned"), **kwargs)
    assert str(err.value).startswith(says) and "\n" not in str(err.value)


@pytest.mark.parametrize("base, says", [
    ("oracle-planner", "rollout base 'oracle-planner' is not a composite of built-in kernels; allowed with "
                       "sparse=True"),
    ("heuristic-tuned", "rollout base 'heuristic-tuned' has no part to solve on a sparse graph"),
])
def test_a_base_the_sparse_rollout_cannot_compile_gets_one_line(base, says):
    with pytest.raises(ValueError) as err:
        Rollout(policies.get(base), budget="sparse:10ms")
    assert str(err.value).startswith(says) and "\n" not in str(err.value)


def test_auto_plays_the_sparse_preset_only_on_city_among_the_suites_worlds():
    from wfbench.policies.lookahead.rollout import plays_sparse

    from wfbench.scenarios import get_suite

    large = {sc.id for sc in get_suite("suite-v1").scenarios
             if plays_sparse(sc.config.max_facilities, sc.config.max_personnel)}
    assert large == {"city-v1"}


def test_auto_is_the_dense_rollout_on_a_small_world_bit_for_bit():
    kw = {"K": 2, "H": 20, "R": 20, "scenario": SMALL}
    tuned = policies.get("solver-tuned")
    auto = Rollout(tuned, sparse="auto", **kw)
    nsw_auto, acted_auto, _ = play(auto, SMALL, SEEDS[:2])
    nsw_dense, acted_dense, _ = play(Rollout(tuned, **kw), SMALL, SEEDS[:2])
    assert np.array_equal(nsw_auto, nsw_dense)
    assert all(np.array_equal(a[k], b[k]) for a, b in zip(acted_auto, acted_dense, strict=True) for k in a)
    assert not auto.sparse and auto.decide == "base" and auto.base is tuned


def test_auto_above_its_size_is_the_sparse_preset_bit_for_bit(monkeypatch):
    from wfbench.policies.lookahead import rollout as module

    monkeypatch.setattr(module, "AUTO_SPARSE_PAIRS", 0)  # every world is large: small plays what city would
    kw = {"K": 2, "H": 20, "scenario": SMALL}
    tuned = policies.get("solver-tuned")
    auto = Rollout(tuned, budget="10ms", sparse="auto", **kw)
    nsw_auto, acted_auto, decided_auto = play(auto, SMALL, SEEDS[:2])
    nsw_preset, acted_preset, decided_preset = play(Rollout(tuned, budget="sparse:10ms", **kw), SMALL, SEEDS[:2])
    assert np.array_equal(nsw_auto, nsw_preset) and np.array_equal(decided_auto, decided_preset)
    assert all(np.array_equal(a[k], b[k]) for a, b in zip(acted_auto, acted_preset, strict=True) for k in a)
    assert auto.sparse and auto.decide == "period"
    assert [p.name for p in auto.futures.parts.values()] == ["assignment-sparse", "staffing", "spatial"]
