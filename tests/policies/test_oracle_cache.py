"""The totals cache (wfbench.policies.oracle.cache): the oracle reuses compiled episodes bit for bit, never stale."""

import copy

import numpy as np
import pytest
from wfbench.policies.oracle import best as best_module
from wfbench.policies.oracle import cache
from wfbench.policies.oracle.best import BestInHindsight

import wfbench
from wfbench import ScenarioConfig, policies
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import results_only
from wfbench.harness.guard import load_policy
from wfbench.harness.runner import run_batch

SMALL = ScenarioConfig.preset("small")
SHORT = SMALL.replace(horizon=120)
COMPILED = ["random", "heuristic", "heuristic-stochastic", "fixed-workforce", "solver", "solver-positioning",
            "heuristic-tuned", "solver-tuned"]


@pytest.fixture
def plays(monkeypatch):
    """The batch sizes of the oracle's compiled plays (roll_forward calls), in order."""
    sizes = []
    real = best_module.roll_forward

    def counted(sim, *args, **kwargs):
        sizes.append(sim.B)
        return real(sim, *args, **kwargs)

    monkeypatch.setattr(best_module, "roll_forward", counted)
    return sizes


def _play(name, config, seeds):
    """The oracle's own compiled play of one candidate: (totals, seeds from the cache)."""
    o = BestInHindsight([name], policies.get)
    o.attach(config)
    return o._play_compiled(policies.get(name), seeds)


def _oracle(candidates, config, seeds, resolve=policies.get):
    o = BestInHindsight(candidates, resolve, name="test")
    o.attach(config)
    o.reset(seeds)
    return o


def test_the_runners_totals_are_the_oracles_own(oracle_totals, monkeypatch):
    """The runner's compiled rollout (reset in the kernel, all threads) and the oracle's roll-forward: the same bits."""
    seeds = np.array([0, 3, 5, 8])
    for name in COMPILED:
        monkeypatch.setenv(cache.ENV, "off")
        want, hits = _play(name, SHORT, seeds)
        assert hits == 0
        monkeypatch.setenv(cache.ENV, str(oracle_totals))
        run_batch(load_policy(name), SHORT, list(seeds))
        codes, hp, pstate = policies.get(name).compiled_plan(seeds, SHORT.max_facilities, SHORT.max_personnel)
        got, found = cache.lookup(cache.policy_key(SHORT, codes, hp), seeds, pstate.keys)
        assert found.all(), name
        assert got.tobytes() == want.tobytes(), name
    assert any(oracle_totals.rglob("*.npz"))  # on disk, for the process backend's workers


def test_a_hit_skips_the_play_and_gives_the_same_choice(oracle_totals, plays):
    seeds = [0, 1, 2, 3]
    first = _oracle(["random", "heuristic", "solver"], SHORT, seeds)
    assert plays == [4, 4, 4] and first.cached == {"random": 0, "heuristic": 0, "solver": 0}
    again = _oracle(["random", "heuristic", "solver"], SHORT, seeds)  # from this process's memory
    assert plays == [4, 4, 4] and again.cached == {"random": 4, "heuristic": 4, "solver": 4}
    cache.clear_memory()
    disk = _oracle(["random", "heuristic", "solver"], SHORT, seeds)  # another process: from the disk
    assert plays == [4, 4, 4] and disk.cached == {"random": 4, "heuristic": 4, "solver": 4}
    for o in (again, disk):
        assert o.scores.tobytes() == first.scores.tobytes() and o.choice == first.choice
    more = _oracle(["random", "heuristic", "solver"], SHORT, [2, 3, 4, 5])  # only the new seeds are played
    assert plays == [4, 4, 4, 2, 2, 2] and more.cached == {"random": 2, "heuristic": 2, "solver": 2}


def test_the_runner_fills_the_cache_for_the_oracle(oracle_totals, plays):
    for name in ("heuristic", "solver"):
        wfbench.evaluate(name, SHORT, seeds=[0, 1, 2])
    o = _oracle(["random", "heuristic", "solver"], SHORT, [0, 1, 2])
    assert plays == [3] and o.cached == {"random": 0, "heuristic": 3, "solver": 3}


def test_a_user_policy_is_not_stored_by_the_runner(oracle_totals):
    """Only a registry name's rollout is stored: a tuner's thousands of trial composites would fill the disk."""
    wfbench.evaluate(policies.get("heuristic"), SHORT, seeds=[0, 1])
    assert not any(oracle_totals.rglob("*.npz"))


def test_a_change_of_parameters_scenario_seed_or_code_misses(oracle_totals, plays, monkeypatch):
    seeds = [0, 1]
    _oracle(["heuristic"], SHORT, seeds)
    assert plays == [2]
    tuned = policies.get("heuristic")
    name, param = next(iter(tuned.tunable.items()))
    tuned = tuned.with_params({name: param.high if tuned.params()[name] != param.high else param.low})
    reseeded = copy.deepcopy(policies.get("heuristic"))
    reseeded.parts["dispatch"].seed = 7
    _oracle(["h"], SHORT, seeds, resolve=lambda _: tuned)  # another hyper-parameter
    _oracle(["h"], SHORT, seeds, resolve=lambda _: reseeded)  # another random key
    _oracle(["heuristic"], SHORT.replace(horizon=119), seeds)  # another scenario
    _oracle(["heuristic"], SHORT.replace(name="renamed"), seeds)  # the canonical JSON differs: a miss, never a hit
    assert plays == [2] * 5
    monkeypatch.setattr(cache, "_CODE", ["another build of the kernels"])  # an edit of the compiled code
    _oracle(["heuristic"], SHORT, seeds)
    assert plays == [2] * 6
    monkeypatch.undo()


def test_off_looks_up_and_stores_nothing(oracle_totals, plays, monkeypatch):
    _oracle(["heuristic"], SHORT, [0, 1])
    monkeypatch.setenv(cache.ENV, "off")
    o = _oracle(["heuristic"], SHORT, [0, 1])
    assert plays == [2, 2] and o.cached == {"heuristic": 0}
    wfbench.evaluate("solver", SHORT, seeds=[0, 1])
    assert cache.directory() is None and len(list(oracle_totals.rglob("*.npz"))) == 1


def test_an_unreadable_file_is_a_miss(oracle_totals, plays):
    _oracle(["heuristic"], SHORT, [0, 1])
    cache.clear_memory()
    for path in oracle_totals.rglob("*.npz"):
        path.write_bytes(b"not an npz")
    o = _oracle(["heuristic"], SHORT, [0, 1])
    assert plays == [2, 2] and o.cached == {"heuristic": 0}


@pytest.fixture
def recorded(monkeypatch):
    """The names of the candidates the oracle played through act, in order."""
    names = []
    real = BestInHindsight._play_recorded

    def counted(self, policy, seeds, best_total):
        names.append(policy.name)
        return real(self, policy, seeds, best_total)

    monkeypatch.setattr(BestInHindsight, "_play_recorded", counted)
    return names


@pytest.mark.slow
def test_a_network_the_runner_played_on_the_same_batch_is_played_again_only_to_be_replayed(oracle_totals, recorded):
    seeds = [0, 1, 2]
    wfbench.evaluate("ppo-joint", SHORT, seeds=seeds)
    alone = _oracle(["ppo-joint"], SHORT, seeds)  # the best everywhere: played once, for its actions
    assert recorded == ["ppo-joint"] and alone.cached == {"ppo-joint": 3}
    recorded.clear()
    beaten = _oracle(["heuristic-tuned", "ppo-joint"], SHORT, seeds)
    assert ("ppo-joint" in beaten.choice) == (recorded == ["ppo-joint"])
    assert beaten.cached["ppo-joint"] == 3
    cache.clear_memory()
    recorded.clear()
    other = _oracle(["ppo-joint"], SHORT, [0, 1])  # another batch: its totals may differ in the last bit: played
    assert recorded == ["ppo-joint"] and other.cached == {"ppo-joint": 0}


def test_a_network_is_keyed_by_its_checkpoint_mode_and_parts(oracle_totals):
    keys = {name: cache.played_key(SHORT, policies.get(name))
            for name in ("ppo-joint", "ppo-joint@greedy", "ppo-dispatch", "impala-joint")}
    assert None not in keys.values() and len(set(keys.values())) == 4
    assert cache.played_key(SHORT, policies.get("ppo-joint")) == keys["ppo-joint"]  # a fresh load: the same key
    assert cache.played_key(SHORT.replace(horizon=119), policies.get("ppo-joint")) != keys["ppo-joint"]
    assert cache.played_key(SHORT, policies.get("oracle-planner")) is None  # not a checkpoint's network
    assert cache.played_key(SHORT, policies.get("heuristic")) is None  # compiled: keyed by policy_key instead


@pytest.mark.slow
def test_the_oracles_rows_are_bit_identical_with_a_networks_totals_from_the_runner(oracle_totals, monkeypatch,
                                                                                  recorded):
    seeds = [0, 1, 2]
    candidates = ["heuristic", "solver", "ppo-joint", "hindsight-joint"]
    monkeypatch.setenv(cache.ENV, "off")
    off = _oracle(candidates, SHORT, seeds)
    monkeypatch.setenv(cache.ENV, str(oracle_totals))
    for name in ("ppo-joint", "hindsight-joint"):
        wfbench.evaluate(name, SHORT, seeds=seeds)
    recorded.clear()
    on = _oracle(candidates, SHORT, seeds)
    assert on.choice == off.choice
    assert set(recorded) == set(on.choice) & {"ppo-joint", "hindsight-joint"}  # only a winner is played
    done = ~np.isnan(off.scores)  # a pruned candidate's score is NaN without the cache, its total with it
    assert on.scores[done].tobytes() == off.scores[done].tobytes()
    sim_off, sim_on = (Simulator(SHORT, seeds, keep_series=False) for _ in range(2))
    for sim, o in ((sim_off, off), (sim_on, on)):
        obs = sim.reset()
        while not sim.done:
            sim.step(o.act(obs))
            obs = sim.observe()
    assert sim_on.state.totals.tobytes() == sim_off.state.totals.tobytes()


def _rows(config, seeds, monkeypatch, oracle_totals, warm_with=()):
    """The oracle's per-seed rows without the cache, then with a cache filled by the runner on ``warm_with``."""
    monkeypatch.setenv(cache.ENV, "off")
    off = wfbench.evaluate("oracle", config, seeds=seeds)
    monkeypatch.setenv(cache.ENV, str(oracle_totals))
    for name, part in warm_with:
        wfbench.evaluate(name, config, seeds=part)
    cold = wfbench.evaluate("oracle", config, seeds=seeds)
    cache.clear_memory()
    warm = wfbench.evaluate("oracle", config, seeds=seeds)  # every compiled candidate from disk
    return off, cold, warm


@pytest.mark.slow
def test_the_oracles_rows_are_bit_identical_with_the_cache_on_small(oracle_totals, monkeypatch):
    seeds = [0, 1, 2]
    # some candidates' seeds come from the runner, the rest are played: mixed batches
    off, cold, warm = _rows(SMALL, seeds, monkeypatch, oracle_totals,
                            warm_with=[("solver-tuned", [1]), ("heuristic", [0, 2]), ("random", seeds),
                                       ("ppo-joint", seeds), ("hindsight-general", [0, 1])])
    for df in (cold, warm):
        assert results_only(df).equals(results_only(off))
        assert df["nsw"].to_numpy().tobytes() == off["nsw"].to_numpy().tobytes()


@pytest.mark.slow
def test_the_oracles_rows_are_bit_identical_with_the_cache_on_a_table2_sized_world(oracle_totals, monkeypatch):
    config = ScenarioConfig.preset("table2-g128-f50-s25")
    seeds = [0, 1]
    off, cold, warm = _rows(config, seeds, monkeypatch, oracle_totals, warm_with=[(n, seeds) for n in COMPILED])
    for df in (cold, warm):
        assert results_only(df).equals(results_only(off))
        assert df["nsw"].to_numpy().tobytes() == off["nsw"].to_numpy().tobytes()
