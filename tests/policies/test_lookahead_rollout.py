"""The rollout lookahead (wfbench.policies.lookahead, issue #43): knobs, presets, the registry, its gain on its base.

Public seeds only (1000-1049): nothing is selected on the test seeds.
"""

import numpy as np
import pytest
from wfbench.policies.lookahead import BUDGETS, Rollout
from wfbench.policies.registry import entries, parse_spec

import wfbench
from tests.conftest import play_episode
from wfbench import ScenarioConfig, policies

SMALL = ScenarioConfig.preset("small")


@pytest.mark.parametrize("knobs, named", [
    ({"K": 0}, "K = 0"), ({"H": -3}, "H = -3"), ({"R": "ten"}, "R = 'ten'"), ({"K": 1.5}, "K = 1.5"),
    ({"H": float("nan")}, "H = nan"), ({"R": True}, "R = True"),
])
def test_bad_knobs_get_one_line_naming_the_knob(knobs, named):
    with pytest.raises(ValueError, match="allowed: an integer >= 1") as err:
        Rollout(policies.get("solver-tuned"), **knobs)
    assert named in str(err.value) and "\n" not in str(err.value)


def test_bad_budget_and_base_are_refused_in_one_line():
    with pytest.raises(ValueError, match="budget '2ms' is not allowed; allowed: 1ms, 10ms, 100ms"):
        Rollout(policies.get("solver-tuned"), budget="2ms")
    with pytest.raises(ValueError, match="not a composite of built-in kernels"):
        Rollout(policies.get("oracle-planner"))


def test_the_presets_are_registered_by_budget():
    rollouts = entries("rollout")  # the MILP's are test_lookahead_mpc.py's, the search's test_search.py's
    assert len(rollouts) == 7
    for e in rollouts:
        name = e.name
        assert parse_spec(name).kind == "lookahead"
        pol = policies.get(name)
        sparse = e.recipe.sparse is True  # the city presets (test_lookahead_sparse.py)
        assert pol.name == name and tuple(pol.settings().values()) == BUDGETS[e.recipe.budget]
        if isinstance(pol, Rollout):  # of a compiled base (the network's: test_lookahead_network.py)
            assert pol.sparse_knob == e.recipe.sparse  # "auto": dense until a world as large as city is seen
            assert pol.sparse == sparse and pol.decide == ("period" if sparse else "base")
            assert (pol.futures is None) != sparse
    assert [e.name for e in rollouts if e.recipe.sparse == "auto"] == ["rollout-solver-tuned",
                                                                       "rollout-solver-tuned-1ms",
                                                                       "rollout-solver-tuned-100ms"]
    assert Rollout(policies.get("solver-tuned"), budget="1ms", H=7).settings() == {"K": 2, "H": 7, "R": 80}


def play(pol, config, seeds):
    sim, actions = play_episode(pol, config, seeds)
    return sim.episode_means()["nsw"], np.stack([a["workforce"] for a in actions])


def test_a_small_rollout_is_not_worse_than_its_base_on_public_seeds():
    config = SMALL.replace(horizon=160)
    seeds = [1000, 1001, 1002]
    base, _ = play(policies.get("solver-tuned"), config, seeds)
    roll = Rollout(policies.get("solver-tuned"), K=2, H=30, R=10)  # the model from the observation (small is flat)
    mine, first = play(roll, config, seeds)
    assert roll.timing["decisions"] > 0
    assert mine.mean() >= base.mean(), (mine, base)
    again, second = play(roll, config, seeds)  # reset starts over: the same seeds, the same episode
    assert np.array_equal(first, second) and np.array_equal(mine, again)



def test_a_rollout_slower_than_the_act_limit_fails_like_any_slow_policy_in_one_line():
    """The issue's bad input: a lookahead handed over as an object (as a user or the board hands one) whose act
    outlasts the act limit is stopped, and told so in one line. Registry names are trusted built-ins: unguarded."""
    from wfbench import evaluate
    from wfbench.harness.guard import PolicyError

    pol = policies.get("rollout-solver-tuned-100ms")
    with pytest.raises(PolicyError) as err:
        evaluate(pol, "paper-64", [1000], act_timeout_s=0.05)
    assert str(err.value).startswith("policy 'rollout-solver-tuned-100ms' did not return from act within the act "
                                     "timeout of 0.05 s") and "\n" not in str(err.value)


@pytest.mark.parametrize("name", ["rollout-solver-tuned-1ms", "rollout-scalefree-general",
                                  "switch-scalefree-general-5ms"])
def test_a_lookahead_shown_more_environments_than_it_was_reset_with_says_so_in_one_line(name):
    # the three lookaheads that build a belief share its start (rollout.start_belief)
    pytest.importorskip("torch")
    pol = policies.get(name)
    pol.reset([1000])
    obs = wfbench.Simulator(SMALL, [1000, 1001]).reset()
    with pytest.raises(RuntimeError) as err:
        pol.act(obs)
    assert str(err.value) == f"{name}: reset with 1 seed(s), observed 2 environment(s)"
    pol.reset([1000, 1001])  # the same policy, reset right, plays
    assert pol.act(obs)["workforce"].shape == (2,)
