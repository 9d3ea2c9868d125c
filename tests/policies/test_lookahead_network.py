"""Rollout with the scale-free network as its base (issue #43): refusals, the registry, replay, the evaluator.

Public seeds only (1000-1049): nothing is selected on the test seeds.
"""

import numpy as np
import pytest
from wfbench.policies.lookahead.network_rollout import NetworkRollout
from wfbench.policies.registry import lookahead_base, parse_spec

import wfbench
from wfbench import ScenarioConfig, Simulator, policies

SMALL = ScenarioConfig.preset("small").replace(horizon=60)


def test_a_base_that_is_not_a_whole_network_is_refused_in_one_line():
    with pytest.raises(ValueError, match="not a network deciding dispatch, workforce and positioning") as err:
        NetworkRollout(policies.get("solver-tuned"))
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="allowed: an integer >= 1"):
        NetworkRollout(policies.get("scalefree-general"), H=0)


def test_it_is_registered_with_its_knobs():
    assert parse_spec("rollout-scalefree-general").kind == "lookahead"
    assert lookahead_base("rollout-scalefree-general") == "scalefree-general"
    pol = policies.get("rollout-scalefree-general")
    assert isinstance(pol, NetworkRollout) and pol.settings() == {"K": 2, "H": 80, "R": 80}


def play(pol, seeds):
    sim = Simulator(SMALL, seeds)
    obs = sim.reset()
    pol.reset(seeds)
    workforce, scores = [], []
    while not sim.done:
        a = pol.act(obs)
        workforce.append(a["workforce"].copy())
        if pol.last_scores is not None:
            scores.append((pol.last_scores.copy(), a["workforce"].copy()))
        sim.step(a)
        obs = sim.observe()
    return sim.episode_means()["nsw"], np.stack(workforce), scores


def test_it_decides_on_scored_candidates_and_replays_the_same_episode():
    pol = NetworkRollout(policies.get("scalefree-general"), K=2, H=8, R=15, scenario=SMALL)
    nsw, first, scores = play(pol, [1000, 1001])
    assert pol.timing["decisions"] >= 2 * (SMALL.horizon // 15)  # every R steps at least
    assert len(scores) >= SMALL.horizon // 15
    for s, w in scores:  # at each decision the action played is a best-scored candidate of its environment
        for b in np.flatnonzero(np.isfinite(s).any(axis=1)):
            assert np.isfinite(s[b, 0])  # the no-op is always a candidate
            assert s[b, w[b]] == np.nanmax(s[b])
    again, second, _ = play(pol, [1000, 1001])  # reset starts over: the same seeds, the same episode
    assert np.array_equal(first, second) and np.array_equal(nsw, again)


def test_the_network_s_own_action_wins_ties():
    pol = NetworkRollout(policies.get("scalefree-general"), K=1, H=1, R=1, scenario=SMALL)
    sim = Simulator(SMALL, [1002])
    obs = sim.reset()
    pol.reset([1002])
    base = policies.get("scalefree-general")
    base.reset([1002])
    a = pol.act(obs)
    own = base.act(obs)["workforce"]
    s = pol.last_scores[0]
    # a one-step roll cannot see a hire work (hire_delay steps): the candidates tie at best, and then the
    # network's own choice stays; where another scores strictly higher, that one is taken
    top = np.nanmax(s)
    assert a["workforce"][0] == (own[0] if s[own[0]] == top else int(np.nanargmax(s)))


@pytest.mark.slow
def test_the_evaluator_hands_it_the_world_and_scores_it():
    df = wfbench.evaluate("rollout-scalefree-general", SMALL, [1003])
    assert df["episode_length"].iloc[0] == SMALL.horizon and 0 < df["nsw"].iloc[0] <= 1
