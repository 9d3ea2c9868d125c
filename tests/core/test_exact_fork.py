"""Exact look-ahead (wfbench.core.fork, wfbench.policies.kernels.forward): a fork follows its source exactly."""

import numpy as np
import pytest
from wfbench.policies import kernels as K
from wfbench.policies.kernels.forward import RollBuffers, roll_forward

from wfbench import ScenarioConfig, Simulator, policies
from wfbench.core.fork import copy_state, fork, fork_index, state_equal
from wfbench.core.state import K_NSW

from . import play

CONFIG = ScenarioConfig.preset("small").replace(horizon=120)
SEEDS = [3, 8, 21]


def random_actions(sim: Simulator, obs: dict, rng: np.random.Generator) -> dict:
    """Valid-looking random actions (some impossible ones too, which the simulator counts)."""
    return play.random_actions(sim.B, sim.M, sim.N, obs, rng, hire_rate=0.08)


def heuristic_actions(pol):
    return lambda sim, obs, rng: pol.act(obs)


def advance(sim: Simulator, steps: int, make, rng) -> list:
    """Step ``sim`` ``steps`` steps (or to the horizon) with actions from ``make``; return them."""
    taken = []
    obs = sim.observe()
    for _ in range(steps):
        if sim.done:
            break
        a = {k: np.array(v, copy=True) for k, v in make(sim, obs, rng).items()}
        taken.append(a)
        sim.step(a)
        obs = sim.observe()
    return taken


@pytest.mark.parametrize("kind", ["random", "heuristic"])
def test_fork_follows_the_source_bit_for_bit(kind):
    sim = Simulator(CONFIG, SEEDS)
    sim.reset()
    pol = policies.get("heuristic")
    pol.reset(SEEDS)
    make = random_actions if kind == "random" else heuristic_actions(pol)
    rng = np.random.default_rng(5)
    advance(sim, 37, make, rng)
    twin = fork(sim, keep_series=True)
    assert twin.t == sim.t == 37 and list(twin.seeds) == SEEDS
    assert state_equal(sim, twin, series=True) == []
    # the same actions on both, to the horizon
    obs = sim.observe()
    while not sim.done:
        a = make(sim, obs, rng)
        sim.step({k: np.array(v, copy=True) for k, v in a.items()})
        twin.step({k: np.array(v, copy=True) for k, v in a.items()})
        obs = sim.observe()
    assert twin.done
    assert state_equal(sim, twin, series=True) == []
    for name, v in sim.episode_means().items():
        assert np.array_equal(v, twin.episode_means()[name]), name
    for name, v in sim.counters().items():
        assert np.array_equal(v, twin.counters()[name]), name
    assert sim.counters()["requests"].sum() > 0 and sim.counters()["visits"].sum() > 0


def test_forking_one_env_equals_a_fresh_single_seed_run():
    rng = np.random.default_rng(11)
    batch = Simulator(CONFIG, SEEDS)
    batch.reset()
    taken = advance(batch, 50, random_actions, rng)
    one = fork(batch, envs=1, keep_series=True)
    alone = Simulator(CONFIG, [SEEDS[1]])
    alone.reset()
    for a in taken:
        alone.step({k: v[1:2] for k, v in a.items()})
    assert state_equal(one, alone, series=True) == []
    # and onward with the same actions
    rng2 = np.random.default_rng(12)
    later = advance(alone, 200, random_actions, rng2)
    for a in later:
        one.step(a)
    assert one.done and state_equal(one, alone, series=True) == []
    assert one.episode_means()["nsw"][0] == alone.episode_means()["nsw"][0]


def test_a_fork_shares_no_mutable_array_with_its_source():
    sim = Simulator(CONFIG, SEEDS)
    sim.reset()
    advance(sim, 20, random_actions, np.random.default_rng(2))
    before = fork(sim)
    copies = fork(sim, envs=[0, 2], copies=3)
    assert copies.B == 6 and list(copies.seeds) == [3, 3, 3, 21, 21, 21]
    assert list(fork_index(3, [0, 2], 3)) == [0, 0, 0, 2, 2, 2]
    advance(copies, 30, random_actions, np.random.default_rng(3))
    assert state_equal(sim, before) == []  # stepping the copies left the source alone
    for field in sim.state:
        for other in copies.state:
            assert not np.shares_memory(field, other)
    # copy_state refreshes a fork in place, rows in any order, trace rows and seeds with them
    copy_state(copies, sim, np.array([2, 1, 0]))
    assert state_equal(copies, sim, rows_a=[0, 1, 2], rows_b=[2, 1, 0]) == []
    assert list(copies.seeds[:3]) == [21, 8, 3]
    assert np.array_equal(copies.trace.arr_t[0], sim.trace.arr_t[2])


def test_fork_rejects_bad_input():
    sim = Simulator(CONFIG, SEEDS)
    with pytest.raises(RuntimeError, match="reset"):
        fork(sim)
    sim.reset()
    with pytest.raises(ValueError, match="envs"):
        fork(sim, envs=3)
    with pytest.raises(ValueError, match="copies"):
        fork(sim, copies=0)


def plan(name: str, seeds, M, N):
    return policies.get(name).compiled_plan(seeds, M, N)


@pytest.mark.parametrize("literal", [False, True], ids=["every-rule", "literal-codes"])
@pytest.mark.parametrize("name", ["heuristic", "solver"])
def test_roll_forward_equals_stepping_the_policy_through_act(name, literal):
    """A roll-forward from the reset state to the horizon is the episode the policy plays through act.

    Both compilations: every rule behind a switch on the codes (the oracle's), and only the
    base's rules, the codes literal (a lookahead's).
    """
    stepped = Simulator(CONFIG, SEEDS)
    obs = stepped.reset()
    pol = policies.get(name)
    pol.reset(SEEDS)
    rolled = fork(stepped)
    codes, hp, ps = plan(name, SEEDS, stepped.M, stepped.N)
    half = roll_forward(rolled, 45, codes, hp, ps, literal=literal).copy()  # in two legs: the state carries over
    assert rolled.t == 45 and np.array_equal(half, rolled.state.totals[:, K_NSW])  # summed in the same order
    rest = roll_forward(rolled, 10_000, codes, hp, ps, literal=literal).copy()
    while not stepped.done:
        stepped.step(pol.act(obs))
        obs = stepped.observe()
    assert rolled.done and state_equal(stepped, rolled) == []
    assert np.allclose(half + rest, stepped.state.totals[:, K_NSW], rtol=1e-12, atol=0)


def test_roll_forward_first_action_equals_a_step_then_the_kernels():
    sim = Simulator(CONFIG, SEEDS)
    sim.reset()
    rng = np.random.default_rng(9)
    advance(sim, 30, random_actions, rng)
    first = random_actions(sim, sim.observe(), rng)
    codes, hp, ps = plan("heuristic", SEEDS, sim.M, sim.N)
    ps2 = K.PolicyState(*(a.copy() for a in ps))
    a = fork(sim)
    buf = RollBuffers(a.B, a.M, a.N)
    buf.first_d[:] = first["dispatch"]
    buf.first_w[:] = first["workforce"]
    buf.first_p[:] = first["positioning"]
    before = a.state.totals[:, K_NSW].copy()
    score = roll_forward(a, 25, codes, hp, ps, first=True, buffers=buf, record=True).copy()
    assert a.t == 55 and np.allclose(score, a.state.totals[:, K_NSW] - before)
    b = fork(sim)
    b.step(first)
    roll_forward(b, 24, codes, hp, ps2)
    assert state_equal(a, b) == []
    # the recorded onsets are the requests that opened, at their facilities' cells
    opened = a.state.counters[:, 8] - sim.state.counters[:, 8]  # C_REQUESTS
    assert np.array_equal(buf.n_onsets, opened) and opened.sum() > 0
    for e in range(a.B):
        cells = {(int(x), int(y)) for x, y in buf.onset_xy[e, : buf.n_onsets[e]]}
        grid = {(int(x), int(y)) for x, y in zip(a.trace.fac0_x[e], a.trace.fac0_y[e], strict=True)}
        grid |= {(int(x), int(y)) for x, y in zip(a.trace.arr_x[e], a.trace.arr_y[e], strict=True)}
        assert cells <= grid


def test_roll_forward_stops_at_the_horizon():
    sim = Simulator(CONFIG, [4])
    sim.reset()
    codes, hp, ps = plan("heuristic", [4], sim.M, sim.N)
    roll_forward(sim, 10_000, codes, hp, ps)
    assert sim.t == CONFIG.horizon and sim.done
    assert roll_forward(sim, 5, codes, hp, ps)[0] == 0.0  # nothing left to run
