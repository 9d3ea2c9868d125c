"""The search's futures critic: ``policies/lookahead/critic.py`` (issue #52).

A :class:`CriticSearch` is the network's search with each future ended at ``L x critic(summary,
L)`` instead of PPO's critic through its map; these tests check that it adds exactly that, at
the right steps left, and refuses what it cannot take in one line.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from wfbench.policies.lookahead.critic import CriticSearch, FuturesCritic, Summary
from wfbench.policies.lookahead.search import NetworkSearch

from tests.conftest import play_episode
from wfbench import ScenarioConfig, policies

SMALL = ScenarioConfig.preset("small").replace(horizon=60)
KNOBS = {"K": 2, "H": 8, "R": 10, "top": 3, "scenario": SMALL}


def constant(per_step: float) -> FuturesCritic:
    """A critic that predicts ``per_step`` NSW per step whatever the state."""
    c = FuturesCritic(d_top=policies.get("scalefree-general").model.top_norm.normalized_shape[0])
    with torch.no_grad():
        for p in c.net.parameters():
            p.zero_()
    c.mean = per_step
    return c


def play(pol, seeds=(1000, 1001)):
    """Every step's actions and, at each decision, (step, the candidates' mean scores)."""
    scores = []
    return play_episode(pol, SMALL, list(seeds), scores)[1], scores


def test_a_future_ends_at_the_steps_left_times_the_critic_s_estimate_per_step():
    base = policies.get("scalefree-general")
    _, plain = play(NetworkSearch(base, z=1e12, value=(), **KNOBS))
    _, scored = play(CriticSearch(base, constant(1.0), z=1e12, **KNOBS))
    assert len(plain) == len(scored) >= SMALL.horizon // KNOBS["R"]
    for (t, a), (t2, b) in zip(plain, scored, strict=True):
        assert t == t2
        left = SMALL.horizon - t - min(KNOBS["H"], SMALL.horizon - t)  # after the future's steps
        seen = ~np.isnan(a)
        assert np.array_equal(seen, ~np.isnan(b))
        np.testing.assert_allclose(b[seen] - a[seen], left, rtol=0, atol=1e-9)


def test_a_critic_that_sees_no_state_decides_as_the_search_on_its_steps_alone():
    # the same estimate for every candidate cancels in their paired differences
    base = policies.get("scalefree-general")
    plain, _ = play(NetworkSearch(base, z=0.5, value=(), **KNOBS), seeds=(1002, 1003))
    scored, _ = play(CriticSearch(base, constant(0.25), z=0.5, **KNOBS), seeds=(1002, 1003))
    for x, y in zip(plain, scored, strict=True):
        for k in x:
            assert np.array_equal(x[k], y[k]), k


def test_a_critic_is_saved_and_loaded_with_the_same_estimates(tmp_path):
    c = FuturesCritic(d_top=12, width=8, seed=3)
    c.mean = 0.7
    c.save(tmp_path / "critic.pt")
    d = FuturesCritic.load(tmp_path / "critic.pt")
    top, left = torch.randn(5, 12), np.array([1, 10, 100, 400, 799])
    assert torch.equal(c.per_step(top, left, 800), d.per_step(top, left, 800))
    assert not torch.equal(c.per_step(top, left, 800), d.per_step(top, left + 1, 800)), "it reads the steps left"


def test_what_it_cannot_take_is_refused_in_one_line(tmp_path):
    base = policies.get("scalefree-general")
    with pytest.raises(ValueError, match=r"^a critic search scores the futures' end with its critic; allowed: "
                                         r"no value knob$"):
        CriticSearch(base, constant(0.0), value=())
    bad = tmp_path / "other.pt"
    torch.save({"weights": {}}, bad)
    with pytest.raises(ValueError, match=r"other\.pt: not a futures critic \(a file written by FuturesCritic\.save\)$"):
        FuturesCritic.load(bad)
    with pytest.raises(ValueError, match=r"^Linear has no top_norm: .*allowed: a scale-free network"):
        Summary(torch.nn.Linear(2, 2))
