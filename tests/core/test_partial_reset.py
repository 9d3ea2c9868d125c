"""Simulator.reset(indices, seeds): the reset rows replay a fresh simulator, the others do not move."""

import numpy as np
import pytest

import wfbench
from wfbench import ScenarioConfig, Simulator
from wfbench.core.state import State

CONFIG = ScenarioConfig.preset("small").replace(horizon=40)


def actions(rng: np.random.Generator, B: int, M: int, N: int) -> dict[str, np.ndarray]:
    """Random well-formed actions (some impossible ones among them: they are ignored and counted)."""
    return {"dispatch": rng.integers(0, N + 1, size=(B, M)), "workforce": rng.integers(0, 7, size=B),
            "positioning": rng.random((B, 2, M))}


def rows(sim: Simulator, obs: dict, b: int) -> dict[str, bytes]:
    """Every state array and observation array of environment b, as bytes."""
    out = {f"state.{k}": np.ascontiguousarray(v[b]).tobytes() for k, v in zip(State._fields, sim.state, strict=True)}
    out.update({f"obs.{k}": np.ascontiguousarray(v[b]).tobytes() for k, v in obs.items()})
    return out


def test_a_reset_environment_replays_a_fresh_simulator_and_the_others_do_not_move():
    seeds = [0, 1, 2, 4]
    A = max(wfbench.trace(CONFIG, s).arr_t.shape[1] for s in seeds)
    new_seed = next(s for s in range(100, 400) if wfbench.trace(CONFIG, s).arr_t.shape[1] > A)  # needs more room
    sim, control = Simulator(CONFIG, seeds), Simulator(CONFIG, seeds)
    B, M, N = sim.B, sim.M, sim.N
    rng = np.random.default_rng(3)
    sim.reset(), control.reset()
    for _ in range(7):
        a = actions(rng, B, M, N)
        sim.step_observe(a), control.step_observe(a)
    before = {b: rows(sim, sim.observe(), b) for b in (0, 2)}
    trace_before = [np.array(x) for x in sim.trace]

    obs = sim.reset(indices=[3, 1], seeds=[new_seed, 1])
    assert sim.trace.arr_t.shape[1] > A, "the new seed's arrivals did not widen the batch's arrays"
    assert sim.seeds.tolist() == [0, 1, 2, new_seed]
    assert sim.state.t.tolist() == [7, 0, 7, 0]
    for b in (0, 2):  # untouched, bit for bit: state, observation rows, trace rows (the padding only grew)
        assert rows(sim, obs, b) == before[b]
        for old, now in zip(trace_before, sim.trace, strict=True):
            assert np.array_equal(now[b, : old.shape[1]] if old.ndim == 2 else now[b], old[b])
    fresh = {b: Simulator(CONFIG, [s]) for b, s in ((1, 1), (3, new_seed))}
    fresh_obs = {b: f.reset() for b, f in fresh.items()}
    for _ in range(30):
        for b, f in fresh.items():
            assert rows(sim, obs, b) == rows(f, fresh_obs[b], 0)
        a = actions(rng, B, M, N)
        r, obs = sim.step_observe(a)
        rc, obs_c = control.step_observe(a)
        for b, f in fresh.items():
            rf, fresh_obs[b] = f.step_observe({k: v[b : b + 1] for k, v in a.items()})
            assert r[b].tobytes() == rf[0].tobytes()
        for b in (0, 2):  # the untouched environments go on exactly as if nothing had been reset
            assert rows(sim, obs, b) == rows(control, obs_c, b)
    assert sim.dones.tolist() == [False] * 4 and not sim.done


def test_a_reset_onto_the_same_seeds_without_seeds_replays_the_episode():
    sim = Simulator(CONFIG, [5, 6])
    first = {k: v.copy() for k, v in sim.reset().items()}
    rng = np.random.default_rng(0)
    for _ in range(5):
        sim.step(actions(rng, 2, sim.M, sim.N))
    obs = sim.reset(indices=np.array([True, False]))
    assert sim.state.t.tolist() == [0, 5]
    for k, v in first.items():
        assert np.array_equal(obs[k][0], v[0]), k
    with pytest.raises(RuntimeError, match="different steps"):
        _ = sim.t


def test_step_refuses_when_some_environments_are_done_and_names_them():
    config = CONFIG.replace(horizon=5)
    sim = Simulator(config, [0, 1, 2])
    sim.reset()
    noop = {"dispatch": np.full((3, sim.M), sim.N), "workforce": np.zeros(3, dtype=np.int64),
            "positioning": np.zeros((3, 2, sim.M))}
    sim.step(noop), sim.step(noop)
    sim.reset(indices=[1])
    while not sim.done:
        sim.step(noop)
    assert sim.dones.tolist() == [True, False, True]
    t = sim.state.t.copy()
    with pytest.raises(RuntimeError, match=r"environment\(s\) \[0, 2\] of 3.*reset\(indices="):
        sim.step(noop)
    assert np.array_equal(sim.state.t, t), "a refused step moved an environment"
    sim.reset(indices=np.flatnonzero(sim.dones), seeds=[7, 8])
    assert sim.seeds.tolist() == [7, 1, 8] and sim.state.t.tolist() == [0, 3, 0] and not sim.done
    sim.step(noop)


def test_step_before_every_environment_was_reset_names_the_others():
    sim = Simulator(CONFIG, [0, 1, 2])
    sim.reset(indices=[0, 2])
    with pytest.raises(RuntimeError, match=r"environment\(s\) \[1\] were never reset"):
        sim.step({"dispatch": np.full((3, sim.M), sim.N), "workforce": np.zeros(3, dtype=np.int64),
                  "positioning": np.zeros((3, 2, sim.M))})
    sim.reset(indices=[1])
    assert sim.state.t.tolist() == [0, 0, 0]


def test_full_reset_onto_new_seeds_equals_a_simulator_made_with_them():
    sim = Simulator(CONFIG, [0, 1])
    sim.reset()
    obs = {k: v.copy() for k, v in sim.reset(seeds=[33, 10]).items()}
    other = Simulator(CONFIG, [33, 10])
    obs_o = other.reset()
    assert sim.seeds.tolist() == [33, 10]
    assert all(rows(sim, obs, b) == rows(other, obs_o, b) for b in range(2))


@pytest.mark.parametrize("indices, seeds, message", [
    ([2], None, r"indices: 2 is out of range; allowed: 0..1"),
    ([-1], None, r"indices: -1 is out of range"),
    ([0, 0], None, r"repeat an environment"),
    ([0.5], None, r"allowed: a 1-D sequence of integers"),
    ([[0]], None, r"allowed: a 1-D sequence of integers"),
    (np.array([True, False, True]), None, r"boolean mask of shape \(3,\); allowed: shape \(2,\)"),
    ([0, 1], [5], r"1 seeds for 2 environments"),
    ([0], [-3], r"seed = -3 is not allowed"),
    ([0], "7", r"seeds = '7' is not allowed"),
    ([0], 7, r"seeds = 7 is not allowed"),
    (None, [1, 2, 3], r"3 seeds for 2 environments"),
])
def test_bad_reset_arguments_are_refused_and_change_nothing(indices, seeds, message):
    sim = Simulator(CONFIG, [0, 1])
    sim.reset()
    sim.step({"dispatch": np.full((2, sim.M), sim.N), "workforce": np.ones(2, dtype=np.int64),
              "positioning": np.ones((2, 2, sim.M))})
    obs = sim.observe()
    before = [rows(sim, obs, b) for b in range(2)], [a.copy() for a in sim.trace], sim.seeds.copy()
    with pytest.raises(ValueError, match=message):
        sim.reset(indices=indices, seeds=seeds)
    assert [rows(sim, obs, b) for b in range(2)] == before[0]
    assert all(np.array_equal(a, b) for a, b in zip(sim.trace, before[1], strict=True))
    assert np.array_equal(sim.seeds, before[2])


def test_an_empty_partial_reset_changes_nothing():
    sim = Simulator(CONFIG, [0, 1])
    obs = sim.reset()
    before = [rows(sim, obs, b) for b in range(2)]
    obs = sim.reset(indices=[], seeds=[])
    assert [rows(sim, obs, b) for b in range(2)] == before
