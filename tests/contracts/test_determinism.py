"""Same seed, same bits: run to run, across processes, alone or in a batch, compiled or stepped."""

import hashlib
import subprocess
import sys

import numpy as np
import pytest
from wfbench.policies import get

from wfbench import ScenarioConfig, Simulator, trace
from wfbench.harness.backends import Execution
from wfbench.harness.budget import results_only
from wfbench.harness.evaluation import evaluate
from wfbench.harness.runner import run_batch
from wfbench.scenarios.resolve import resolve_scenario

PAPER = ScenarioConfig.preset("paper-64")


def digest(series: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(series).tobytes()).hexdigest()


def test_trace_is_a_pure_function():
    config = ScenarioConfig.preset("paper-64")
    a, b = trace(config, 7), trace(config, 7)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x, y)
    c = trace(config, 8)
    assert not np.array_equal(a.fac0_x, c.fac0_x)


@pytest.mark.parametrize("policy", ["heuristic", "heuristic-stochastic", "random", "solver"])
def test_seed_alone_equals_seed_in_batch_of_64(policy):
    batch = run_batch(policy, PAPER, list(range(64)), keep_series=True, threads=2)
    for seed in (0, 17, 63):
        alone = run_batch(policy, PAPER, [seed], keep_series=True, threads=1)
        assert np.array_equal(alone.series[0], batch.series[seed]), f"seed {seed} differs alone vs in batch"


@pytest.mark.parametrize("policy", ["heuristic", "heuristic-stochastic", "random", "solver"])
def test_compiled_rollout_equals_python_step_loop(policy):
    seeds = [3, 4, 5]
    compiled = run_batch(policy, PAPER, seeds, keep_series=True)
    sim = Simulator(resolve_scenario("paper-64"), seeds)
    obs = sim.reset()
    p = get(policy)
    p.reset(seeds)
    while not sim.done:
        sim.step(p.act(obs))
        obs = sim.observe()
    assert np.array_equal(compiled.series, sim.state.series)


def test_step_observe_equals_step_then_observe():
    """The environments' fused, bound call gives the same rewards, observations and state."""
    seeds = [1, 2]
    a, b = Simulator(resolve_scenario("paper-64"), seeds), Simulator(resolve_scenario("paper-64"), seeds)
    obs_a, obs_b = a.reset(), b.reset()
    p, q = get("random"), get("random")
    p.reset(seeds)
    q.reset(seeds)
    while not a.done:
        r_a = a.step(p.act(obs_a))
        obs_a = a.observe()
        r_b, obs_b = b.step_observe(q.act(obs_b))
        assert np.array_equal(r_a, r_b)
        assert obs_a.keys() == obs_b.keys()
        for k in obs_a:
            assert np.array_equal(obs_a[k], obs_b[k]), k
    for x, y in zip(a.state, b.state, strict=True):
        assert np.array_equal(x, y)


def test_fingerprint_separates_what_numba_types_apart():
    """The bound entry points are cached by this fingerprint: whatever numba types
    differently must fingerprint differently, or a call would misread its arguments."""
    import numba

    from wfbench.core.entrypoints import _fingerprint

    a = np.zeros((3, 4))
    ro = a.copy()
    ro.flags.writeable = False
    values = [a, a.astype(np.float32), a.astype(np.int64), a[None], np.asfortranarray(a), a[:, ::2], ro,
              (a, a), (a, a.astype(np.int64)), 1, 2**63, 1.0, True, np.int32(1), np.float32(1.0)]
    for x in values:
        for y in values:
            if _fingerprint(x) == _fingerprint(y):
                assert numba.typeof(x) == numba.typeof(y), (x, y)
    assert len({_fingerprint(x) for x in values}) == len({numba.typeof(x) for x in values})


@pytest.mark.slow
def test_backends_agree():
    serial = evaluate("heuristic-stochastic", "small", 6)
    process = evaluate("heuristic-stochastic", "small", 6, execution=Execution(backend="process", workers=2))
    assert results_only(serial).equals(results_only(process))  # the budget columns are measurements


@pytest.mark.slow
def test_same_bits_in_another_process():
    here = digest(run_batch("heuristic", PAPER, [11], keep_series=True).series)
    code = ("import hashlib, numpy as np; from wfbench import ScenarioConfig; from wfbench.harness.runner import "
            "run_batch; s = run_batch('heuristic', ScenarioConfig.preset('paper-64'), [11], keep_series=True).series; "
            "print(hashlib.sha256(np.ascontiguousarray(s).tobytes()).hexdigest())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == here


def test_env_reset_with_same_seed_repeats_the_episode():
    import wfbench

    env = wfbench.parallel_env("small")

    def run():
        obs, _ = env.reset(seed=9)
        rewards = []
        for t in range(50):
            actions = {"dispatch": np.full(8, 8), "workforce": t % 7, "positioning": np.full((2, 8), 0.5, np.float32)}
            obs, r, *_ = env.step(actions)
            rewards.append(r["dispatch"])
        return rewards

    assert run() == run()
