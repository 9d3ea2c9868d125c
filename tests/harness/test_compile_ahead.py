"""Compiling in a second process (wfbench.harness.runner.compile_ahead): only where code is compiled moves.

On a cold cache, while the runner plays a built-in policy through ``act``, a second process
compiles the simulator's step, for the oracle the rules its candidates act with while this
one compiles the roll-forward, and for a rollout its futures' roll-forward (docs/performance.md,
"Cold compile"). No number may move, and a second process that fails changes nothing.
"""

import numpy as np
import pytest
from wfbench.policies.kernels.act import act_range
from wfbench.policies.kernels.forward import roll_range
from wfbench.policies.lookahead.ahead import compile_roll, rollout_job
from wfbench.policies.oracle import best as best_module
from wfbench.policies.oracle import cache as totals_cache
from wfbench.policies.oracle.best import BestInHindsight, act_plans, compile_for_act

from wfbench import ScenarioConfig, policies
from wfbench.harness import runner
from wfbench.harness.guard import LoadedPolicy
from wfbench.harness.runner import run_batch

SHORT = ScenarioConfig.preset("small").replace(horizon=12)


class Nearest:
    """A user's dispatch in Python: the composite it is part of is not compiled whole."""

    decisions = ("dispatch",)

    def reset(self, seeds):
        pass

    def act(self, obs):
        B, M = obs["requesting"].shape
        return {"dispatch": np.full((B, M), obs["personnel"].shape[1], dtype=np.int64)}


def _mixed():
    return policies.Composite(dispatch=Nearest(), workforce="threshold", positioning="spatial")


def _resolve(name):
    return _mixed() if name == "mixed" else policies.get(name)


CANDIDATES = ["random", "mixed", "heuristic"]


@pytest.fixture(autouse=True)
def no_totals(monkeypatch):
    """Every play plays (no totals from an earlier one): the same code path each time."""
    monkeypatch.setenv(totals_cache.ENV, "off")
    totals_cache.clear_memory()


def test_the_plans_are_the_compilations_the_candidates_use():
    """What the second process compiles is what the candidates' act calls: the same codes, the same types."""
    plans = act_plans([_resolve(n) for n in CANDIDATES])
    assert sorted(tuple(c.tolist()) for c, _ in plans) == [(0, 0, 1), (0, 1, 0)]  # the mixed one's built-in parts
    compile_for_act(SHORT, plans)  # here, in this process: numba's compilations of act_range it made or loaded
    before = set(act_range.signatures)
    oracle = BestInHindsight(CANDIDATES, _resolve)
    oracle.attach(SHORT)
    oracle.reset([0, 1])
    assert set(act_range.signatures) == before, "the candidates needed another compilation than the plans"


def _play(seeds=(0, 1)):
    """The oracle through the runner, as a built-in (no guard), as ``wfbench evaluate --policy oracle`` plays it."""
    oracle = BestInHindsight(CANDIDATES, _resolve)
    result = run_batch(LoadedPolicy(oracle, "oracle", None), SHORT, list(seeds), threads=1)
    return oracle, result


def _same(a, b):
    (oa, ra), (ob, rb) = a, b
    assert oa.choice == ob.choice
    np.testing.assert_array_equal(oa.scores, ob.scores)
    assert ra.means.keys() == rb.means.keys()
    for k in ra.means:
        np.testing.assert_array_equal(ra.means[k], rb.means[k])
    for k in ra.counters:
        np.testing.assert_array_equal(ra.counters[k], rb.counters[k])
    np.testing.assert_array_equal(ra.steps, rb.steps)


@pytest.fixture
def started(monkeypatch):
    """The runner takes the cache for cold (it starts the second process's jobs); the futures it started."""
    futures = []
    real = runner.compile_ahead

    def recorded(*args):
        futures.append(real(*args))
        return futures[-1]

    monkeypatch.setattr(runner, "has_entries", lambda dispatcher: False)
    monkeypatch.setattr(runner, "compile_ahead", recorded)
    return futures


def test_the_second_process_changes_no_number(started, monkeypatch):
    with_child = _play()
    assert len(started) == 2 and None not in started  # the step, the candidates' rules (two cores or more)
    for future in started:
        assert future.result(timeout=300) is None  # the second process did its jobs
    monkeypatch.setattr(runner, "compile_ahead", lambda *args: None)  # no second process at all
    _same(with_child, _play())


def test_a_failing_second_process_falls_back(started, monkeypatch, capfd):
    monkeypatch.setattr(best_module, "act_plans", lambda policies: [(np.zeros(2, dtype=np.int64), np.zeros(1))])
    played = _play()
    with pytest.raises(IndexError):
        started[1].result(timeout=300)  # the job failed over there ...
    monkeypatch.setattr(runner, "compile_ahead", lambda *args: None)
    _same(played, _play())  # ... and nothing here noticed
    assert "Traceback" not in capfd.readouterr().err


def test_one_core_starts_nothing(monkeypatch):
    monkeypatch.setattr(runner, "_cores", lambda: 1)
    assert runner.compile_ahead("nothing", print) is None


def test_warm_starts_nothing(monkeypatch):
    """The oracle asks for nothing where the roll-forward is on disk."""
    oracle = BestInHindsight(CANDIDATES, _resolve)
    oracle.attach(SHORT)
    assert oracle.compile_ahead(lambda dispatcher: True) is None


def test_cold_is_read_from_the_index():
    """A function compiled and cached here has entries on disk; one never cached has none."""
    assert runner.has_entries(act_range)  # compiled by the tests above, or loaded: cache=True
    assert not runner.has_entries(print)  # no numba cache at all: taken for cold


# -- the rollout: its futures' roll-forward compiled in the second process ---------------------------
def _rollout():
    return policies.get("rollout-solver-tuned-1ms")


def test_the_rollout_compiles_ahead_what_its_decisions_roll():
    """compile_roll compiles the roll-forward its decisions then call: no other signature, nothing else played."""
    r = _rollout()
    r.set_world(runner.public_world(SHORT))
    what, job, args = rollout_job(r, lambda dispatcher: False)
    assert job is compile_roll and len(args) == 1 and args[0] is not r and "futures" in what
    job(*args)  # here, as the second process would
    before = set(roll_range.signatures)
    run_batch(LoadedPolicy(r, "rollout-solver-tuned-1ms", None), SHORT, [0, 1], threads=1)
    assert r.timing["rolls"] > 0, "the rollout decided nothing: the check would be empty"
    assert set(roll_range.signatures) == before, "the decisions needed another roll-forward than the one compiled"


def test_the_rollouts_second_process_changes_no_number(started, monkeypatch):
    def play():
        return run_batch(LoadedPolicy(_rollout(), "rollout-solver-tuned-1ms", None), SHORT, [0, 1], threads=1)

    with_child = play()
    assert len(started) == 2 and None not in started  # the step, the futures' roll-forward
    for future in started:
        assert future.result(timeout=300) is None
    monkeypatch.setattr(runner, "compile_ahead", lambda *args: None)
    alone = play()
    for k in with_child.means:
        np.testing.assert_array_equal(with_child.means[k], alone.means[k])
    for k in with_child.counters:
        np.testing.assert_array_equal(with_child.counters[k], alone.counters[k])


def test_a_warm_or_worldless_rollout_starts_nothing():
    r = _rollout()
    assert rollout_job(r, lambda dispatcher: False) is None  # no public world yet: nothing to build it for
    r.set_world(runner.public_world(SHORT))
    assert rollout_job(r, lambda dispatcher: True) is None
    assert rollout_job(policies.get("heuristic"), lambda dispatcher: False) is None  # no rollout: nothing
