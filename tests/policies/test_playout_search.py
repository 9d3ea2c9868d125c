"""The search with its futures played to the episode's end (issue #52): what it plays, where, and its refusals.

Its future blindness is the leak test's (``tests/policies/test_future_leak.py``, over every
registered lookahead). Public seeds only (1000-1049).
"""

import numpy as np
import pytest
from wfbench.policies.lookahead import playout, rollout
from wfbench.policies.lookahead.playout import PlayoutSearch
from wfbench.policies.lookahead.search import BUDGETS, NetworkSearch, value_map
from wfbench.policies.registry import lookahead_base, parse_spec

from tests.conftest import play_episode
from wfbench import ScenarioConfig, policies

SMALL = ScenarioConfig.preset("small").replace(horizon=60)
SEEDS = [1000, 1001]


def actions(pol, config=SMALL, seeds=SEEDS) -> list[dict[str, np.ndarray]]:
    return play_episode(pol, config, seeds)[1]


def same(x: list[dict], y: list[dict]) -> None:
    assert len(x) == len(y)
    for t, (a, b) in enumerate(zip(x, y, strict=True)):
        for k in a:
            assert np.array_equal(a[k], b[k]), (t, k)


def test_the_preset_is_registered_beside_the_truncated_ones():
    name = "search-scalefree-general-playout"
    assert parse_spec(name).kind == "lookahead" and lookahead_base(name) == "scalefree-general"
    pol = policies.get(name)
    K, R, top, z = playout.BUDGETS["100ms"]
    assert type(pol) is PlayoutSearch and pol.name == name
    assert pol.settings() == {"K": K, "H": "end", "R": R, "top": top, "z": z, "futures": "greedy", "large": "10ms"}


@pytest.mark.slow
def test_it_plays_the_truncated_search_with_its_futures_to_the_end_and_no_value():
    net = policies.get("scalefree-general")
    pol = PlayoutSearch(net, K=2, R=10, top=2, scenario=SMALL)
    got = actions(pol)
    assert pol.H == SMALL.horizon and pol.value == () and (pol.K, pol.R, pol.top, pol.z) == (2, 10, 2, 1.0)
    assert pol.timing["decisions"] >= len(SEEDS) * SMALL.horizon // 10, "it deliberated every R steps"
    ref = NetworkSearch(policies.get("scalefree-general"), K=2, H=SMALL.horizon, R=10, top=2, z=1.0, value=(),
                        scenario=SMALL)
    same(got, actions(ref))
    short = NetworkSearch(policies.get("scalefree-general"), K=2, H=5, R=10, top=2, z=1.0, value=(), scenario=SMALL)
    cut = actions(short)
    assert any(not np.array_equal(a["workforce"], b["workforce"]) for a, b in zip(got, cut, strict=True)), \
        "a 5-step future decides as a played-out one: the test cannot tell them apart"


def test_on_a_world_as_large_as_city_it_is_the_10ms_search(monkeypatch):
    monkeypatch.setattr(rollout, "AUTO_SPARSE_PAIRS", 0)  # every world is "as large as city"
    pol = PlayoutSearch(policies.get("scalefree-general"), scenario=SMALL)
    got = actions(pol)
    assert (pol.K, pol.H, pol.R, pol.top, pol.z) == BUDGETS["10ms"] and pol.period
    assert pol.value == value_map("scalefree-general", SMALL.name) and pol.value
    same(got, actions(NetworkSearch(policies.get("scalefree-general"), budget="10ms", scenario=SMALL)))


@pytest.mark.parametrize(("knobs", "expected"), [
    ({"budget": "10ms"}, "playout search budget '10ms' is not allowed; allowed: 100ms"),
    ({"K": 1}, "search knob K = 1 is not allowed; allowed: an integer >= 2"),
    ({"top": 0}, "search knob top = 0 is not allowed; allowed: an integer >= 1"),
    ({"z": -1.0}, "search knob z = -1.0 is not allowed; allowed: a number > 0"),
    ({"large": "5ms"}, "search budget '5ms' is not allowed; allowed: 1ms, 10ms, 100ms"),
])
def test_a_bad_knob_or_preset_is_refused_in_one_line_naming_it(knobs, expected):
    with pytest.raises(ValueError) as err:
        PlayoutSearch(policies.get("scalefree-general"), **knobs)
    assert "\n" not in str(err.value) and expected in str(err.value), str(err.value)
    with pytest.raises(ValueError, match="not a network deciding dispatch, workforce and positioning"):
        PlayoutSearch(policies.get("solver-tuned"))
