"""The networks before the scale-free one compute only the dispatch rows they read, with the bits of the whole block.

A deployed network's sampler reads the dispatch rows of the facilities with a real
choice (about 3% on ``city``). ``WorkforceNet.heads`` with ``at`` computes those rows
alone (the pointer product stays whole, the elementwise rest is done on the rows), the
policy draws their noise compactly, and the actions must be those of the whole block:
the published numbers of every shipped network are these actions.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from wfbench.policies.neural import dist, scalefree
from wfbench.policies.neural.model import WorkforceNet, model_config
from wfbench.policies.neural.policy import NetworkPolicy

from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario

SEEDS = [11, 12, 13]


def with_blocks() -> NetworkPolicy:
    """A joint network whose attention reads the whole distance block (preset tiny: one block), fixed weights."""
    torch.manual_seed(5)
    return NetworkPolicy(WorkforceNet(model_config("tiny")), name="tiny-blocks")


def driven(scenario: str, steps: int):
    """Observations of ``SEEDS`` on ``scenario`` along the heuristic's episode (many open requests on large)."""
    sim = Simulator(resolve_scenario(scenario), SEEDS, keep_series=False, threads=1)
    obs = sim.reset()
    drive = policies.get("heuristic")
    drive.reset(SEEDS)
    for _ in range(steps):
        yield obs, sim
        obs = sim.step_observe(drive.act(obs))[1]


@pytest.mark.parametrize("make", [lambda: policies.get("ppo-joint"), with_blocks], ids=["no-blocks", "blocks"])
def test_the_compact_rows_are_the_rows_of_the_whole_block(make):
    pol = make()
    model = pol.model
    state = model.initial_state(len(SEEDS))
    starts = torch.zeros(1, len(SEEDS))
    compared = 0
    with torch.no_grad():
        for obs, _ in driven("large", 25):
            raw = scalefree.raw_tensors(model, obs)
            whole_x = scalefree.features(model, raw)
            rows_x = scalefree.features(model, raw, rows_only=True)
            # the distance block is left out only where nothing but the dispatch rows reads it
            assert ("dist" in rows_x) == model.reads_whole_distance
            choose = scalefree.compact_rows(model, whole_x)
            at = choose.nonzero(as_tuple=True)
            whole, _ = model(whole_x, state, starts)
            part, _ = model(rows_x, state, starts, at)
            assert part["dispatch"].shape == (int(choose.sum()), whole["dispatch"].shape[-1])
            assert torch.equal(part["dispatch"], whole["dispatch"][at])
            for key in whole:
                if key != "dispatch":
                    assert torch.equal(part[key], whole[key]), key
            compared += int(choose.sum())
    assert compared > 50  # facilities with a real choice were met


def test_the_compact_noise_is_the_full_noise_of_the_rows_read():
    a, b = policies.get("ppo-joint"), policies.get("ppo-joint")
    a.reset(SEEDS)
    b.reset(SEEDS)
    for obs, sim in driven("large", 15):
        x = scalefree.features(a.model, scalefree.raw_tensors(a.model, obs))
        rows = dist.choosing(x).numpy()
        whole = a._noise(sim.B, sim.M, sim.N, rows)
        compact = b._noise(sim.B, sim.M, sim.N, rows, rows)
        assert torch.equal(compact["dispatch"], whole["dispatch"][torch.from_numpy(rows)])
        for key in whole:
            if key != "dispatch":
                assert torch.equal(compact[key], whole[key]), key
    # both generators stand at the same place afterwards
    none = np.zeros((sim.B, sim.M), dtype=bool)
    assert torch.equal(a._noise(sim.B, sim.M, sim.N, none)["workforce"],
                       b._noise(sim.B, sim.M, sim.N, none)["workforce"])


def whole_block_act(pol: NetworkPolicy, obs, state, starts):
    """The deployed decision as it was before the compact rows: the whole block, the whole noise."""
    B, M = obs["requesting"].shape
    N = obs["personnel"].shape[1]
    x = scalefree.features(pol.model, scalefree.raw_tensors(pol.model, obs))
    out, state = pol.model(x, state, starts)
    noise = None
    if pol.mode != "greedy":
        read = pol.mode == "sample" and "dispatch" in pol.decisions
        rows = scalefree.dispatch_rows(pol.model, x) if read else torch.zeros(B, M, dtype=torch.bool)
        noise = pol._noise(B, M, N, rows.numpy())
    acts = scalefree.sample(pol.model, out, x, noise)
    return {k: v.numpy() for k, v in acts.items()}, state


@pytest.mark.parametrize("mode", ["sample", "greedy", "greedy-dispatch"])
@pytest.mark.parametrize("name", ["ppo-joint", "ppo-independent"])
def test_the_actions_are_those_of_the_whole_block(name, mode):
    deployed = policies.get(f"{name}@{mode}") if mode != "sample" else policies.get(name)
    reference = policies.get(f"{name}@{mode}") if mode != "sample" else policies.get(name)
    deployed.reset(SEEDS)
    reference.reset(SEEDS)
    state = reference.model.initial_state(len(SEEDS))
    starts = torch.ones(1, len(SEEDS))
    sent = 0
    with torch.no_grad():
        for obs, _ in driven("large", 20):
            mine = deployed.act(obs)
            theirs, state = whole_block_act(reference, obs, state, starts)
            starts = torch.zeros_like(starts)
            assert np.array_equal(mine["dispatch"], theirs["dispatch"])
            assert np.array_equal(mine["workforce"], theirs["workforce"])
            assert np.array_equal(mine["positioning"], dist.positioning_weights(
                torch.from_numpy(theirs["positioning"]), obs["requesting"].shape[1]).numpy())
            sent += int((mine["dispatch"] < obs["personnel"].shape[1]).sum())
    assert sent > 0


class PlainModel(torch.nn.Module):
    """A model of one's own with only the documented interface (docs/rl.md): the plain ``forward``, no ``at``."""

    def __init__(self, inner: WorkforceNet):
        super().__init__()
        self.inner, self.config = inner, inner.config

    def initial_state(self, B, device=None):
        return self.inner.initial_state(B, device)

    def forward(self, x, state, starts):
        assert "dist" in x  # it gets the whole block, as before
        return self.inner(x, state, starts)


def test_a_model_without_compact_rows_gets_the_whole_block_and_the_same_actions():
    shipped = policies.get("ppo-joint")
    plain = NetworkPolicy(PlainModel(shipped.model), name="plain")
    shipped.reset(SEEDS)
    plain.reset(SEEDS)
    for obs, _ in driven("large", 12):
        mine, theirs = plain.act(obs), shipped.act(obs)
        for key in theirs:
            assert np.array_equal(mine[key], theirs[key]), key
