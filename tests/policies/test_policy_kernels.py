"""The built-in dispatch, workforce and positioning rules (docs/model.md, Policies), probed through ``act``.

Each test builds an observation by hand (``wfbench.core.observe.make_obs``) and checks a
decision against the rule worked out by hand; randomized rules are checked by their
frequencies over many environment seeds (one batch, so one call).
"""

import numpy as np
import pytest

from wfbench import policies
from wfbench.core.observe import FACILITY_FEATURES, GLOBAL_FEATURES, make_obs

DOWNTIME = FACILITY_FEATURES.index("downtime")
PUR = GLOBAL_FEATURES.index("utilization")


def act(decision, name, obs, seeds=(0,), policy=None):
    pol = policy or policies.DECISIONS[decision][name]()
    if policy is None:
        pol.reset(list(seeds))
    return pol.act(obs)[decision]


def batch(obs, B):
    return {k: np.repeat(v, B, axis=0) for k, v in obs.items()}


def shares(values, outcomes):
    return np.array([(values == o).mean() for o in outcomes])


# -- dispatch ---------------------------------------------------------------------------------------
def test_nearest__measures_from_the_current_position_not_the_home():
    # person 0 lives far away but stands next to the request; person 1 is at home, farther
    obs = make_obs(1, 2, facilities=[(8, 8, True)], people=[(0, 0, 9, 9, 1), (6, 6, 6, 6, 1)])
    assert act("dispatch", "nearest", obs)[0].tolist() == [0], "nearest dispatch must send person 0 (distance 2)"


def test_nearest__ties_go_to_the_lowest_person_then_the_lowest_facility():
    two_people = make_obs(1, 2, facilities=[(5, 5, True)], people=[(0, 5, 0, 5, 1), (10, 5, 10, 5, 1)])
    assert act("dispatch", "nearest", two_people)[0].tolist() == [0], "equal distances: the lowest person slot"
    two_requests = make_obs(2, 1, facilities=[(0, 5, True), (10, 5, True)], people=[(5, 5, 5, 5, 1)])
    assert act("dispatch", "nearest", two_requests)[0].tolist() == [0, 1], (
        "equal distances: the lowest facility slot gets the person, the other the no-op (N = 1)")


def test_inverse_distance__samples_people_in_proportion_to_one_over_one_plus_distance():
    B = 4000
    obs = batch(make_obs(1, 3, facilities=[(0, 0, True)],
                         people=[(0, 0, 0, 0, 1), (1, 0, 1, 0, 1), (0, 3, 0, 3, 1)]), B)
    picks = act("dispatch", "inverse-distance", obs, seeds=range(B))[:, 0]
    w = np.array([1 / 1, 1 / 2, 1 / 4])  # distances 0, 1, 3
    np.testing.assert_allclose(shares(picks, [0, 1, 2]), w / w.sum(), atol=0.035,  # > 4 standard deviations
                               err_msg="inverse-distance dispatch: P(person) must be ~ 1 / (1 + distance)")


def test_random_dispatch__chooses_the_noop_and_each_free_person_alike():
    B = 4000
    obs = batch(make_obs(1, 3, facilities=[(0, 0, True)],
                         people=[(0, 0, 0, 0, 1), (5, 5, 5, 5, 1), (9, 9, 9, 9, 1)]), B)
    picks = act("dispatch", "random", obs, seeds=range(B))[:, 0]
    np.testing.assert_allclose(shares(picks, [0, 1, 2, 3]), 0.25, atol=0.035,
                               err_msg="random dispatch: the no-op (3) and each free person with probability 1/4")


# -- workforce --------------------------------------------------------------------------------------
def test_random_workforce__chooses_uniformly_among_the_valid_actions():
    B = 5000
    obs = batch(make_obs(1, 3, facilities=[(0, 0, False)], people=[(0, 0, 0, 0, 1)], t=100), B)
    obs["workforce_mask"][:] = [1, 1, 1, 1, 0, 1, 0]
    a = act("workforce", "random", obs, seeds=range(B))
    np.testing.assert_allclose(shares(a, range(7)), [0.2, 0.2, 0.2, 0.2, 0, 0.2, 0], atol=0.03,
                               err_msg="random workforce: each of the 5 valid actions with probability 1/5")


def test_epsilon_greedy__replaces_two_percent_of_decisions_by_a_random_one():
    B = 6000
    obs = batch(make_obs(1, 3, facilities=[(0, 0, False)], people=[(0, 0, 0, 0, 0), (1, 1, 1, 1, 1)], t=100), B)
    obs["globals"][:, PUR] = 0.6  # the threshold rule does nothing here
    a = act("workforce", "threshold-epsilon", obs, seeds=range(B))
    # with probability 0.02 a uniform choice of (hire, let go, nothing): an action in 2 of 3 cases
    rate, want = (a != 0).mean(), 0.02 * 2 / 3
    assert abs(rate - want) < 4 * np.sqrt(want / B), f"epsilon-greedy acted in {rate:.4f} of steps, expected {want:.4f}"


# -- positioning ------------------------------------------------------------------------------------
def test_spatial__maps_mix_request_rate_and_downtime_scaled_by_their_maxima():
    """Two steps worked by hand: smoothing 0.01 counts only new requests; request weight 0.5."""
    pol = policies.DECISIONS["positioning"]["spatial"]()
    pol.reset([0])
    # slot 3 stays inactive: both maps are 0 there
    first = make_obs(4, 1, facilities=[(0, 0, True), (5, 5, False), (9, 9, True)], people=[(1, 1, 1, 1, 1)], t=60)
    first["facilities"][0, :3, DOWNTIME] = (0.5, 0.2, 0.0)
    out = act("positioning", "spatial", first, policy=pol)[0]
    # rates: new requests at 0 and 2 -> 0.01, 0, 0.01, scaled: 1, 0, 1; downtime scaled: 1, 0.4, 0
    demand = 0.5 * np.array([1, 0, 1]) + 0.5 * np.array([1.0, float(np.float32(0.2)) / 0.5, 0.0])
    np.testing.assert_allclose(out[0], [*demand / demand.max(), 0], atol=1e-7, err_msg="hire map, step 1")
    np.testing.assert_allclose(out[1], [*(1 - demand / demand.max()), 0], atol=1e-7, err_msg="let-go map, step 1")
    # next step: 0 still requesting (not new), 1 newly requesting, 2 repaired
    second = make_obs(4, 1, facilities=[(0, 0, True), (5, 5, True), (9, 9, False)], people=[(1, 1, 1, 1, 1)], t=61)
    second["facilities"][0, :3, DOWNTIME] = (0.6, 0.3, 0.1)
    out = act("positioning", "spatial", second, policy=pol)[0]
    rate = np.array([0.99 * 0.01, 0.01, 0.99 * 0.01])
    down = second["facilities"][0, :3, DOWNTIME].astype(float)
    demand = 0.5 * rate / rate.max() + 0.5 * down / down.max()
    np.testing.assert_allclose(out[0], [*demand / demand.max(), 0], atol=1e-7, err_msg="hire map, step 2")
    np.testing.assert_allclose(out[1], [*(1 - demand / demand.max()), 0], atol=1e-7, err_msg="let-go map, step 2")


def test_random_positioning__rows_are_independent_uniform_draws():
    B = 3000
    obs = batch(make_obs(2, 1, facilities=[(0, 0, False), (3, 3, True)], people=[(1, 1, 1, 1, 1)]), B)
    out = act("positioning", "random", obs, seeds=range(B))
    assert ((out >= 0) & (out <= 1)).all()
    hire, let_go = out[:, 0, :].ravel(), out[:, 1, :].ravel()
    assert abs(hire.mean() - 0.5) < 0.03 and abs(let_go.mean() - 0.5) < 0.03, "weights must be uniform on [0, 1]"
    assert abs(np.corrcoef(hire, let_go)[0, 1]) < 0.08, "the hire and let-go rows must be independent draws"


@pytest.mark.parametrize("name", ["spatial", "spatial-gaussian", "random"])
def test_positioning__weights_are_in_the_unit_interval(name):
    obs = batch(make_obs(3, 1, facilities=[(0, 0, True), (3, 3, False), (6, 1, True)], people=[(1, 1, 1, 1, 1)]), 50)
    out = act("positioning", name, obs, seeds=range(50))
    assert out.shape == (50, 2, 3) and ((out >= 0) & (out <= 1)).all(), f"{name}: weights outside [0, 1]"
