"""The deployed network's sampling: the same picks and noise as the plain definitions, drawn for less.

The dispatch rule (:func:`dist.pick_in_slot_order`) is computed without a loop over
facilities, and the deployed policy draws only the noise rows its sampler reads
(``NetworkPolicy._noise``); both must give exactly what the plain versions give: a
facility-by-facility loop, and a generator that draws every row.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from wfbench.policies.neural import dist, scalefree
from wfbench.policies.neural.policy import POLICY_SEED

from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario


def loop_picks(logits, valid, cand, rows, R, N):
    """The rule as written: facilities in order, each excluding the people taken before it in its environment."""
    C, K = cand.shape
    taken = [set() for _ in range(R)]
    out = []
    for i in range(C):
        allowed = [bool(valid[i, c]) and int(cand[i, c]) not in taken[int(rows[i])] for c in range(K)] + [True]
        lg = torch.where(torch.tensor(allowed), logits[i], torch.full_like(logits[i], dist.NEG))
        j = int(lg.argmax())
        person = int(cand[i, j]) if j < K else N
        if person < N:
            taken[int(rows[i])].add(person)
        out.append(person)
    return out


@pytest.mark.parametrize("k", [None, 3])  # every person a column (the networks before the scale-free one), or k
def test_picks_equal_the_facility_by_facility_loop(k):
    gen = torch.Generator().manual_seed(7)
    R, N, per_env = 5, 6, 9  # more facilities than people: repeats, several rounds
    rows = torch.arange(R).repeat_interleave(per_env)
    C = rows.numel()
    if k is None:
        cand = torch.arange(N).expand(C, N)
    else:
        cand = torch.stack([torch.randperm(N, generator=gen)[:k] for _ in range(C)])
    K = cand.shape[1]
    valid = torch.rand(C, K, generator=gen) < 0.8
    logits = torch.randn(C, K + 1, generator=gen) * 3
    logits[:, K] -= 4.0  # the no-op less likely: most facilities send someone
    logits[::7, 0] = logits[::7, 1]  # ties: the first index wins in both
    allowed = torch.zeros(C, K + 1, dtype=torch.bool)
    allowed[:, K] = True
    pick, person = dist.pick_in_slot_order(logits, allowed, valid, cand, rows, R, N)
    assert person.tolist() == loop_picks(logits, valid, cand, rows, R, N)
    sent = person[person < N]
    assert sent.numel() > R  # the case is not empty: people were sent, and repeats were resolved
    for r in range(R):
        mine = person[(rows == r) & (person < N)]
        assert mine.unique().numel() == mine.numel()
    assert ((pick == K) == (person == N)).all()


def full_noise(policy, seeds, B, M, N, steps):
    """The noise of each step as the policy drew it before: every row of every head, from fresh generators."""
    rngs = [np.random.default_rng([int(s), policy.seed, POLICY_SEED]) for s in seeds]
    sizes = {k: s[1:] for k, s in scalefree.noise_shapes(policy.model, B, M, N).items()}
    total = sum(int(np.prod(s)) for s in sizes.values())
    out = []
    for _ in range(steps):
        u = np.stack([rng.random(total) for rng in rngs]).clip(1e-10, 1.0 - 1e-7)
        g = torch.from_numpy(-np.log(-np.log(u))).float()
        step, at = {}, 0
        for key, s in sizes.items():
            n = int(np.prod(s))
            step[key] = g[:, at:at + n].reshape(B, *s)
            at += n
        out.append(step)
    return out


@pytest.mark.parametrize("name", ["ppo-joint", "scalefree-general"])
def test_the_noise_read_is_the_noise_of_a_full_draw(name):
    pol = policies.get(name)
    seeds = [3, 4, 5]
    sim = Simulator(resolve_scenario("paper-64"), seeds, keep_series=False, threads=1)
    obs = sim.reset()
    pol.reset(seeds)
    steps, read_rows = 12, 0
    reference = full_noise(pol, seeds, sim.B, sim.M, sim.N, 2 * steps)  # two draws per step below
    for t in range(steps):
        x = scalefree.features(pol.model, scalefree.raw_tensors(pol.model, obs))
        rows = scalefree.dispatch_rows(pol.model, x)
        noise = pol._noise(sim.B, sim.M, sim.N, rows.numpy())
        for key, ref in reference[2 * t].items():
            if key == "dispatch":
                assert torch.equal(noise[key][rows], ref[rows]), t
                assert not noise[key][~rows].any()  # nobody reads them: not drawn
            else:
                assert torch.equal(noise[key], ref), (t, key)
        read_rows += int(rows.sum())
        obs = sim.step_observe(pol.act(obs))[1]  # act draws the next step's noise: same stream position as above
    assert read_rows > 0
    # after the run the generators stand where drawing every row leaves them
    probe = full_noise(pol, seeds, sim.B, sim.M, sim.N, 2 * steps + 1)[-1]
    nxt = pol._noise(sim.B, sim.M, sim.N, np.zeros((sim.B, sim.M), dtype=bool))
    assert torch.equal(nxt["workforce"], probe["workforce"])


@pytest.mark.parametrize("M", [50, 200, 1000])  # 200 is large-v1 and table2-g32-f100-s25; 1000 is city
def test_every_choosing_facility_picks_in_slot_order_at_any_size(M):
    """Issue #42: before e4684f9 the slot order was an int8 key, ``(~requesting) * M + slot``, which wraps at
    M >= 128 and put idle facilities first, so that most requesting ones never picked (large-v1: 879 visits
    where the rule gives 1,965). The order must be the slots' for any M, as the trainer's log-probability reads it."""
    gen = torch.Generator().manual_seed(M)
    B, N = 2, 40
    requesting = torch.rand(B, M, generator=gen) < 0.3
    mask = torch.rand(B, M, N + 1, generator=gen) < 0.5
    mask[..., N] = True
    logits = torch.randn(B, M, N + 1, generator=gen)
    logits[..., N] = -10.0  # the no-op last: a facility sends someone while anyone it may send is free
    acts = dist.sample({"dispatch": logits}, {"dispatch_mask": mask, "requesting": requesting}, None)["dispatch"]
    for b in range(B):
        rows_b = torch.nonzero(requesting[b] & mask[b, :, :N].any(-1)).squeeze(-1)
        expected = loop_picks(logits[b, rows_b], mask[b, rows_b, :N], torch.arange(N).expand(len(rows_b), N),
                              torch.zeros(len(rows_b), dtype=torch.long), 1, N)
        assert acts[b, rows_b].tolist() == expected
        assert (acts[b, ~requesting[b]] == N).all()
        assert (acts[b] < N).sum() >= min(N, len(rows_b)) - 5  # nearly everyone free is sent somewhere
