"""The switch among a network's training seeds (issue #52): its knobs, its deliberations, its members, the registry.

Its future blindness is the leak test's (``tests/policies/test_future_leak.py``, parametrized over
every registered lookahead). Public seeds only (1000-1049): nothing is selected on the test seeds.
"""

import numpy as np
import pytest
from wfbench.policies.lookahead.switch import BUDGETS, SeedSwitch
from wfbench.policies.registry import lookahead_base, lookahead_names, parse_spec, seed_members

from wfbench import ScenarioConfig, Simulator, policies
from wfbench.reproduce import provenance

SMALL = ScenarioConfig.preset("small").replace(horizon=60)


def members(*specs: str) -> list:
    return [policies.get(s) for s in specs]


def play(pol, config, seeds):
    """Every step's actions, and which member each environment follows after each step."""
    sim = Simulator(config, seeds)
    obs = sim.reset()
    pol.reset(seeds)
    actions, follow = [], []
    while not sim.done:
        a = pol.act(obs)
        actions.append({k: np.array(v, copy=True) for k, v in a.items()})
        follow.append(np.array(getattr(pol, "follow", []), copy=True))
        sim.step(a)
        obs = sim.observe()
    return sim.episode_means()["nsw"], actions, follow


def test_bad_knobs_futures_and_members_are_refused_in_one_line():
    two = members("scalefree-general", "scalefree-general#seed0")
    cases = [({"K": 1}, r"^switch knob K = 1 is not allowed; allowed: an integer >= 2 \(sampled futures per "
                        r"network\)$"),
             ({"K": 2.5}, r"^switch knob K = 2.5 is not allowed; allowed: an integer >= 2"),
             ({"K": "4"}, r"^switch knob K = '4' is not allowed; allowed: an integer >= 2"),
             ({"R": 0}, r"^switch knob R = 0 is not allowed; allowed: an integer >= 1 \(steps between two "
                        r"deliberations"),
             ({"z": 0}, r"^switch knob z = 0 is not allowed; allowed: a number > 0"),
             ({"z": -1.0}, r"^switch knob z = -1.0 is not allowed; allowed: a number > 0"),
             ({"z": float("nan")}, r"^switch knob z = nan is not allowed; allowed: a number > 0"),
             ({"budget": "1s"}, r"^switch budget '1s' is not allowed; allowed: 5ms, 10ms$"),
             ({"futures": "mean"}, r"^switch futures 'mean' is not allowed; allowed: greedy, sample ")]
    for knobs, message in cases:
        with pytest.raises(ValueError, match=message):
            SeedSwitch(two, **knobs)
    with pytest.raises(ValueError, match=r"^switch members: 1 given; allowed: two or more networks$"):
        SeedSwitch(two[:1])
    with pytest.raises(ValueError, match=r"^switch member 'solver-tuned' is not a network deciding dispatch, "
                                         r"workforce and positioning; allowed: NetworkPolicy objects"):
        SeedSwitch([two[0], policies.get("solver-tuned")])


def test_a_switch_between_a_network_and_its_copy_never_switches_and_acts_as_the_network():
    """Equal members give equal futures: no advantage passes the test, and every action is the first member's."""
    seeds = [1000, 1001]
    pol = SeedSwitch(members("scalefree-general", "scalefree-general#seed2"), K=2, R=20, scenario=SMALL)
    nsw, acted, follow = play(pol, SMALL, seeds)
    assert pol.timing["decisions"] == 3 * len(seeds) and pol.timing["switches"] == 0  # t = 0, 20 and 40
    assert all((f == 0).all() for f in follow)
    ref_nsw, ref, _ = play(policies.get("scalefree-general"), SMALL, seeds)
    assert np.array_equal(nsw, ref_nsw)
    for a, b in zip(acted, ref, strict=True):
        assert all(np.array_equal(a[k], b[k]) for k in b)


def test_it_follows_the_member_whose_futures_score_best_and_only_it_acts_after_the_last_deliberation():
    """A member that never hires or lets go beside the network: the futures tell which is better, per environment.

    After the last deliberation (R = the horizon: only at t = 0) only the members followed step.
    """
    seeds = [1000, 1001, 1002]
    pol = SeedSwitch(members("scalefree-general", "scalefree-general#seed0", "scalefree-general#seed4"), K=3,
                     R=SMALL.horizon, z=0.5, scenario=SMALL)
    calls = {i: 0 for i in range(3)}
    for i, m in enumerate(pol.members):
        act = m.act

        def counted(obs, i=i, act=act):
            calls[i] += 1
            return act(obs)

        m.act = counted
    _, acted, follow = play(pol, SMALL, seeds)
    order, mean, se = pol.last_test[0]
    assert len(order) == 3 and order[0] == 0 and mean.shape == se.shape == (3,)
    chosen = follow[0]
    for b in range(len(seeds)):  # the rule of beyond_noise, on the scores it kept
        order, mean, se = pol.last_test[b]
        ok = [c for c in range(1, 3) if mean[c] > 0.5 * se[c] and mean[c] > 0]
        expected = order[max(ok, key=lambda c: mean[c])] if ok else 0
        assert chosen[b] == expected
    assert all(np.array_equal(f, chosen) for f in follow)  # never again
    steps = SMALL.horizon
    for i in range(3):  # every member acts at t = 0; after it, the ones followed act every step, the others never
        assert calls[i] == (steps if i in set(chosen.tolist()) else 1), (i, calls, chosen)


def test_the_registry_builds_it_from_the_shipped_pick_and_the_other_seeds():
    assert "switch-scalefree-general" in lookahead_names() and parse_spec("switch-scalefree-general").kind == \
        "lookahead"
    assert lookahead_base("switch-scalefree-general") == "scalefree-general"
    pol = policies.get("switch-scalefree-general")
    assert isinstance(pol, SeedSwitch) and pol.name == "switch-scalefree-general"
    assert (pol.K, pol.R, pol.z, pol.futures) == (*BUDGETS["10ms"], "sample")
    names = [m.name for m in pol.members]
    assert names[0] == "scalefree-general" and len(names) == len(seed_members("scalefree-general"))
    shipped = policies.get("scalefree-general").model.state_dict()
    for m in pol.members[1:]:  # the shipped pick is not in twice
        assert any(not np.array_equal(v.numpy(), m.model.state_dict()[k].numpy()) for k, v in shipped.items())
    net = "policies/neural/checkpoints/scalefree-general"
    assert list(provenance.policy_inputs("switch-scalefree-general")) == [
        *(f"{net}-seed{k}.pt" for k in range(5)), f"{net}.pt"]  # every member's file decides its episodes
    cheap = policies.get("switch-scalefree-general-5ms")  # the 5 ms preset: half the futures, the same members
    assert (cheap.K, cheap.R, cheap.z) == BUDGETS["5ms"] and cheap.K < pol.K and cheap.name.endswith("-5ms")
    assert [m.name for m in cheap.members] == names


@pytest.mark.slow
def test_it_is_not_below_the_shipped_network_on_a_small_public_world():
    """paper-64's public seeds 1000-1003: it follows the better seeds where the futures say so (docs/policies.md)."""
    import wfbench

    seeds = [1000, 1001, 1002, 1003]
    nsw = wfbench.evaluate("switch-scalefree-general", "paper-64", seeds)["nsw"].to_numpy()
    base = wfbench.evaluate("scalefree-general", "paper-64", seeds)["nsw"].to_numpy()
    assert (nsw - base).mean() >= -0.002, nsw - base
