"""The search with a compiled tail: ``policies/lookahead/tail.py`` (issue #52).

A :class:`TailSearch` is the network's search whose futures a compiled composite plays to the
episode's end after the network's H steps; these tests check that the tail adds the rest of
the episode and nothing where no step is left, that it still acts as its network with a huge z,
and that what it cannot take is refused in one line.
"""

from __future__ import annotations

import numpy as np
import pytest
from wfbench.policies.lookahead.search import NetworkSearch
from wfbench.policies.lookahead.tail import TailSearch

from tests.conftest import play_episode
from wfbench import ScenarioConfig, policies

SMALL = ScenarioConfig.preset("small").replace(horizon=60)
KNOBS = {"K": 2, "R": 10, "top": 3, "scenario": SMALL}


def play(pol, seeds=(1000, 1001)):
    """Every step's actions and, at each decision, (step, the candidates' mean scores)."""
    scores = []
    return play_episode(pol, SMALL, list(seeds), scores)[1], scores


@pytest.mark.slow
def test_the_tail_adds_the_rest_of_the_episode_and_the_network_still_acts_with_a_huge_z():
    base, H = policies.get("scalefree-general"), 8
    net, _ = play(policies.get("scalefree-general"))
    acted, plain = play(NetworkSearch(base, H=H, z=1e12, value=(), **KNOBS))
    tailed, scored = play(TailSearch(base, policies.get("heuristic"), H=H, z=1e12, **KNOBS))
    for x, y in zip(net, tailed, strict=True):  # a huge z: the network's own actions at every step
        for k in x:
            assert np.array_equal(x[k], y[k]), k
    assert len(plain) == len(scored) >= SMALL.horizon // KNOBS["R"]
    spread = False
    for (t, a), (t2, b) in zip(plain, scored, strict=True):
        assert t == t2
        left = SMALL.horizon - t - min(H, SMALL.horizon - t)  # the steps the tail plays
        seen = ~np.isnan(a)
        assert np.array_equal(seen, ~np.isnan(b))
        rest = b[seen] - a[seen]  # the mean over the futures of the NSW the tail summed, each step in [0, 1]
        if left == 0:
            assert np.array_equal(rest, np.zeros_like(rest))
        else:
            assert np.all(rest > 0.2 * left) and np.all(rest <= left), (t, rest, left)
            spread |= np.ptp(rest) > 0
    assert spread, "the candidates' tails never differed: the tail does not play from their states"


@pytest.mark.slow
def test_with_futures_past_the_horizon_it_is_the_search_on_its_futures_alone():
    base = policies.get("scalefree-general")
    x, a = play(NetworkSearch(base, H=SMALL.horizon, z=0.5, value=(), **KNOBS), seeds=(1002, 1003))
    y, b = play(TailSearch(base, policies.get("heuristic"), H=SMALL.horizon, z=0.5, **KNOBS), seeds=(1002, 1003))
    for u, v in zip(x, y, strict=True):
        for k in u:
            assert np.array_equal(u[k], v[k]), k
    for (t, s), (t2, s2) in zip(a, b, strict=True):
        assert t == t2 and np.array_equal(s, s2, equal_nan=True)


def test_what_it_cannot_take_is_refused_in_one_line():
    base = policies.get("scalefree-general")
    with pytest.raises(ValueError, match=r"^a tail search scores the rest of each future by its tail's play; "
                                         r"allowed: no value knob$"):
        TailSearch(base, policies.get("heuristic"), value=())
    with pytest.raises(ValueError, match=r"^search tail 'scalefree-general' is not a composite of built-in kernels; "
                                         r"allowed: a compiled composite such as heuristic-tuned-train$"):
        TailSearch(base, base)
