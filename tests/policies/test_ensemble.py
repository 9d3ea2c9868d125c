"""An ensemble of scale-free networks acts on the mean of its members' logits, and one member is that network."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.ensemble import EnsembleNet
from wfbench.policies.neural.policy import NetworkPolicy, build_model, load_checkpoint

from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario

SEEDS = [1000, 1001]
CKPT = str(Path(__file__).resolve().parents[2] / "policies/neural/checkpoints/scalefree-general-seed{}.pt")


def member(i: int):
    return build_model(load_checkpoint(CKPT.format(i)))


def actions(policy: NetworkPolicy, steps: int = 60) -> list[dict[str, np.ndarray]]:
    sim = Simulator(resolve_scenario("small"), SEEDS, keep_series=False, threads=1)
    obs = sim.reset()
    policy.reset(SEEDS)
    out = []
    for _ in range(steps):
        act = policy.act(obs)
        out.append(act)
        obs = sim.step_observe(act)[1]
    return out


@pytest.mark.parametrize("mode", ["sample", "greedy"])
def test_an_ensemble_of_one_network_acts_as_that_network(mode):
    alone = actions(NetworkPolicy(member(2), mode=mode))
    one = actions(NetworkPolicy(EnsembleNet([member(2)]), mode=mode))
    for a, b in zip(alone, one, strict=True):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])


def test_the_heads_are_the_mean_of_the_members_and_each_keeps_its_memory():
    nets = [member(1), member(4)]
    ens = EnsembleNet(nets)
    sim = Simulator(resolve_scenario("small"), SEEDS, keep_series=False, threads=1)
    obs = sim.reset()
    x = scalefree.features(ens, scalefree.raw_tensors(ens, obs))
    starts = torch.ones(1, len(SEEDS))
    with torch.no_grad():
        out, state = ens(x, ens.initial_state(len(SEEDS)), starts)
        own = [n(x, n.initial_state(len(SEEDS)), starts) for n in nets]
    for k in ("value", "workforce", "dispatch"):
        torch.testing.assert_close(out[k], (own[0][0][k] + own[1][0][k]) / 2, rtol=0, atol=1e-6)
    for (h, c), (_, (h2, c2)) in zip(state, own, strict=True):
        assert torch.equal(h, h2) and torch.equal(c, c2)
    # the members disagree, so the mean is neither of them
    assert not torch.allclose(out["workforce"], own[0][0]["workforce"])
    rows = torch.arange(len(SEEDS))
    which = torch.zeros(len(SEEDS), dtype=torch.long)
    with torch.no_grad():
        pos = ens.positioning(out, rows, which)
        want = (nets[0].positioning(own[0][0], rows, which) + nets[1].positioning(own[1][0], rows, which)) / 2
    torch.testing.assert_close(pos, want, rtol=0, atol=1e-6)


def test_networks_of_other_configurations_are_refused_in_one_line():
    other = scalefree.ScaleFreeNet(scalefree.ScaleFreeConfig.from_dict({**member(0).config.to_dict(), "d": 16}))
    with pytest.raises(ValueError, match=r"^an ensemble's networks must be scalefree networks of one configuration; "
                                         r"got 2 networks of 2 configurations$"):
        EnsembleNet([member(0), other])
    with pytest.raises(ValueError, match="at least one network"):
        EnsembleNet([])
