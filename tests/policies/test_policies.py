import numpy as np
import pytest
from wfbench.policies import Composite, get

from wfbench import Simulator, policies
from wfbench.harness.budget import results_only
from wfbench.harness.evaluation import evaluate, summarize


def test_entry_point_to_a_policy_factory():
    pol = get("tests.policies.test_policies:make_policy")
    assert isinstance(pol, Composite)


def make_policy():
    return Composite("nearest", "fixed", "none")


def test_unknown_entry_point_attribute():
    with pytest.raises(ValueError, match="has no attribute"):
        get("wfbench.policies.registry:nothing_here")


def test_heuristic_beats_random_on_paper_64():
    h = evaluate("heuristic", "paper-64", 10)
    r = evaluate("random", "paper-64", 10)
    assert h["nsw"].mean() > r["nsw"].mean()
    assert (h["nsw"].values > r["nsw"].values).all(), "heuristic should win on every common seed"


def test_nearest_dispatch_sends_the_closest_free_person(tiny):
    sim = Simulator(tiny, [0])
    sim.reset()
    S = sim.state
    S.fac_down[0, :] = False
    S.fac_down[0, 2] = True
    S.fac_assigned[0, 2] = -1
    obs = sim.observe()
    fx, fy = obs["facilities"][0, 2, :2]
    dist = np.abs(obs["personnel"][0, :, 2] - fx) + np.abs(obs["personnel"][0, :, 3] - fy)
    pol = policies.DECISIONS["dispatch"]["nearest"]()
    pol.reset([0])
    out = pol.act(obs)["dispatch"][0]
    assert out[2] == int(np.argmin(dist))
    assert (np.delete(out, 2) == tiny.max_personnel).all()


def test_threshold_hires_when_over_utilized_and_respects_cooldown(tiny):
    sim = Simulator(tiny, [0])
    obs = sim.reset()
    pol = policies.DECISIONS["workforce"]["threshold"]()
    pol.reset([0])
    obs["globals"][0, 8] = 0.95
    obs["t"][0] = 100
    a = pol.act(obs)["workforce"][0]
    assert a == 0, "all slots taken in the tiny scenario: no hire is possible"
    obs["globals"][0, 8] = 0.1
    a = pol.act(obs)["workforce"][0]
    assert a in (4, 5, 6)
    assert pol.act(obs)["workforce"][0] == 0, "cooldown"


def test_fixed_workforce_keeps_headcount():
    df = evaluate("fixed-workforce", "small", 3)
    assert (df["hires"] == 0).all() and (df["releases"] == 0).all()


def test_stochastic_variants_differ_by_seed_but_repeat():
    a = evaluate("heuristic-stochastic", "small", [1, 2])
    b = evaluate("heuristic-stochastic", "small", [1, 2])
    assert results_only(a).equals(results_only(b))  # the budget columns are measurements
    assert summarize(a)["nsw"][0] > 0
