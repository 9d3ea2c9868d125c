"""Compiling in a second process (wfbench.harness.runner.compile_ahead): only where code is compiled moves.

On a cold cache, while the runner plays a built-in policy through ``act``, a second process
compiles the simulator's step, for the oracle the rules its candidates act with while this
one compiles the roll-forward, and for a rollout its futures' roll-forward (docs/performance.md,
"Cold compile"). No number may move, and a second process that fails changes nothing.
"""

import threading

import numpy as np
import pytest
from wfbench.policies.kernels.act import act_range
from wfbench.policies.kernels.forward import roll_range
from wfbench.policies.lookahead.ahead import compile_roll, rollout_job
from wfbench.policies.oracle import ahead as oracle_ahead
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

    def recorded(*args, **kwargs):
        futures.append(real(*args, **kwargs))
        return futures[-1]

    monkeypatch.setattr(runner, "has_entries", lambda dispatcher: False)
    monkeypatch.setattr(runner, "compile_ahead", recorded)
    return futures


def test_the_second_process_changes_no_number(started, monkeypatch):
    with_child = _play()
    assert len(started) == 3 and None not in started  # the kernels, the step, the candidates' rules (two cores or more)
    for future in started:
        assert future.result(timeout=300) is None  # the second process did its jobs
    monkeypatch.setattr(runner, "compile_ahead", lambda *args, **kwargs: None)  # no second process at all
    _same(with_child, _play())


def test_a_failing_second_process_falls_back(started, monkeypatch, capfd):
    monkeypatch.setattr(best_module, "act_plans", lambda policies: [(np.zeros(2, dtype=np.int64), np.zeros(1))])
    played = _play()
    with pytest.raises(IndexError):
        started[-1].result(timeout=300)  # the job failed over there (the candidates' rules, after the step) ...
    monkeypatch.setattr(runner, "compile_ahead", lambda *args, **kwargs: None)
    _same(played, _play())  # ... and nothing here noticed
    assert "Traceback" not in capfd.readouterr().err


# -- this process waits for what the second one is compiling, rather than compile it again -------------
KERNEL = """
import numba

@numba.njit(cache=True)
def twice(x):
    return 2 * x
"""
JOB = """
import sys, time
sys.path.insert(0, {folder!r})
time.sleep({delay})  # this process asks first: the job is still running
import kernel_for_ahead
kernel_for_ahead.twice(3)  # compiles and caches twice(int64)
"""


@pytest.mark.slow
def test_this_process_waits_for_the_job_and_loads_what_it_compiled(tmp_path, monkeypatch):
    """A real second process compiles a cold function; asked for it meanwhile, this one loads it from disk."""
    import importlib
    import runpy

    (tmp_path / "kernel_for_ahead.py").write_text(KERNEL)
    (tmp_path / "job.py").write_text(JOB.format(folder=str(tmp_path), delay=2.0))
    monkeypatch.syspath_prepend(str(tmp_path))
    kernel = importlib.import_module("kernel_for_ahead")
    future = runner.compile_ahead("a test kernel", runpy.run_path, str(tmp_path / "job.py"), waits=(kernel.twice,))
    assert future is not None
    assert not future.done()
    assert kernel.twice(3) == 6  # cold here: it waited for the job, then read the disk
    assert future.done()
    assert sum(kernel.twice.stats.cache_hits.values()) == 1, "this process did not load the job's compilation"
    assert not kernel.twice.stats.cache_misses, "this process compiled the function a second time"
    assert "load_overload" not in kernel.twice._cache.__dict__  # undone with the job


class _Cache:
    """numba's on-disk cache as the wait sees it: empty until ``filled``."""

    def __init__(self):
        self.filled, self.reads = False, 0

    def load_overload(self, sig, target_context):
        self.reads += 1
        return "loaded" if self.filled else None


class _Dispatcher:
    def __init__(self):
        self._cache = _Cache()


def test_a_miss_waits_for_the_job_then_reads_again():
    from concurrent.futures import Future

    dispatcher, future = _Dispatcher(), Future()
    assert runner.wait_on_miss(dispatcher, future, limit_s=30)

    def finish():
        dispatcher._cache.filled = True
        future.set_result(None)

    threading.Timer(0.5, finish).start()
    assert dispatcher._cache.load_overload("sig", None) == "loaded"
    assert dispatcher._cache.reads >= 3  # before the wait, while the job ran, after it
    assert "load_overload" not in dispatcher._cache.__dict__  # undone: later misses compile at once


def test_a_miss_loads_what_the_job_cached_before_the_job_is_done():
    """A job that compiles several functions hands each over when it is on disk, not at the job's end."""
    import time
    from concurrent.futures import Future

    dispatcher, future = _Dispatcher(), Future()
    assert runner.wait_on_miss(dispatcher, future, limit_s=30)
    threading.Timer(0.3, setattr, (dispatcher._cache, "filled", True)).start()
    t = time.monotonic()
    assert dispatcher._cache.load_overload("sig", None) == "loaded"
    assert time.monotonic() - t < 5 and not future.done()  # read while the job still runs
    assert "load_overload" in dispatcher._cache.__dict__  # the job may cache another signature: still waiting
    future.set_result(None)
    assert "load_overload" not in dispatcher._cache.__dict__  # undone with the job


def test_a_failed_or_late_job_leaves_the_compilation_here():
    from concurrent.futures import Future

    failed, future = _Dispatcher(), Future()
    runner.wait_on_miss(failed, future, limit_s=30)
    threading.Timer(0.1, future.set_exception, (RuntimeError("the job failed"),)).start()
    assert failed._cache.load_overload("sig", None) is None  # compile here, no exception raised
    late = _Dispatcher()
    runner.wait_on_miss(late, Future(), limit_s=0.1)  # never done
    assert late._cache.load_overload("sig", None) is None
    assert not runner.wait_on_miss(object(), Future())  # not a numba dispatcher: nothing changed


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
    what, job, args, waits = rollout_job(r, lambda dispatcher: False)
    assert job is compile_roll and len(args) == 1 and args[0] is not r and "futures" in what
    assert waits == (roll_range,)
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
    monkeypatch.setattr(runner, "compile_ahead", lambda *args, **kwargs: None)
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


# -- the oracle: its roll-forward's facility-location kernels, compiled by the second process first ----------
def test_the_oracle_s_jobs_compile_the_kernels_first_and_its_candidates_rules_last():
    oracle = BestInHindsight(CANDIDATES, _resolve)
    oracle.attach(SHORT)
    (what, job, args, waits), (what2, job2, args2, waits2) = oracle_ahead.oracle_job(oracle, lambda dispatcher: False)
    assert job is oracle_ahead.compile_kernels and args == () and waits == oracle_ahead.KERNELS
    assert "facility-location kernels" in what
    assert job2 is compile_for_act and args2[0] is SHORT and waits2 == (act_range,)  # the oracle's own, as before
    assert what2 == "the built-in rules the oracle's candidates act with"
    assert oracle_ahead.oracle_job(oracle, lambda dispatcher: True) is None  # warm: nothing
    job()
    sig = oracle_ahead.kernel_signature()
    assert all(sig in [tuple(s) for s in k.signatures] for k in oracle_ahead.KERNELS)


def test_the_oracle_s_jobs_queue_with_the_step_between_in_one_line(monkeypatch, capsys):
    queued = []
    monkeypatch.setattr(runner.jit, "load_factor", lambda: 1.0)
    monkeypatch.setattr(runner, "has_entries", lambda dispatcher: False)
    monkeypatch.setattr(runner, "compile_ahead",
                        lambda what, fn, *args, waits=(), announce=True: queued.append((fn, waits)) or object())
    oracle = BestInHindsight(CANDIDATES, _resolve)
    oracle.attach(SHORT)
    runner.start_compile_ahead(oracle, SHORT)
    assert [fn for fn, _ in queued] == [oracle_ahead.compile_kernels, runner.step_once, compile_for_act]
    assert queued[1][1] == runner.STEP_WAITS
    err = capsys.readouterr().err.splitlines()
    assert err == ["wfbench: compiling the oracle's facility-location kernels, then the simulator's step, then the "
                   "built-in rules the oracle's candidates act with in a second process meanwhile (on another core); "
                   "cached afterwards; here meanwhile the oracle's every-rule roll-forward, ~45 s on an idle 2-core VM"]
    # one line for the three jobs, in their order, and for what this process compiles


def test_the_oracle_s_networks_are_its_last_job_in_the_same_line(monkeypatch, capsys, oracle_totals):
    from concurrent.futures import Future

    queued = []
    monkeypatch.setattr(runner, "has_entries", lambda dispatcher: False)
    monkeypatch.setattr(runner.jit, "load_factor", lambda: 2.0)
    futures = []

    def queue(what, fn, *args, waits=(), announce=True):
        queued.append((fn, args))
        futures.append(Future())
        return futures[-1]

    monkeypatch.setattr(runner, "compile_ahead", queue)
    oracle = BestInHindsight(NETWORKS, policies.get)
    oracle.attach(SHORT)
    runner.start_compile_ahead(oracle, SHORT, seeds=[5, 6])
    for future in futures:  # done: the wait on the totals cache undoes itself
        future.set_result(None)
    assert totals_cache.lookup is LOOKUP
    assert [fn for fn, _ in queued] == [oracle_ahead.compile_kernels, runner.step_once, compile_for_act,
                                        oracle_ahead.play_networks]
    config, resolve, keys, seeds, claims = queued[-1][1]
    assert config is SHORT and resolve is policies.get and list(keys) == NETWORKS[2:] and seeds == [5, 6]
    assert keys == {n: totals_cache.played_key(SHORT, policies.get(n)) for n in NETWORKS[2:]}
    err = capsys.readouterr().err
    assert "then the built-in rules the oracle's candidates act with, then playing the oracle's network candidates' " \
           "episodes (their totals handed back) in a second process" in err
    assert err.endswith("here meanwhile the oracle's every-rule roll-forward, ~90 s (45 s on an idle 2-core VM, "
                        "x2.0 for the current load)\n")


def test_the_kernel_signature_is_what_the_candidates_pass():
    """The types of the kernels' arguments on a real observation and state: those of kernel_signature."""
    from numba import typeof
    from wfbench.policies import kernels as K
    from wfbench.policies.protocol import as_obs

    from wfbench.core.simulator import Simulator

    sim = Simulator(SHORT, [0, 1], keep_series=False, threads=1)
    obs = sim.reset()
    B, M, N = sim.B, sim.M, sim.N
    hp = np.zeros((3, len(K.HP_FIELDS)))
    p = np.zeros((B, 2, M))
    b, t = 1, np.asarray(obs["t"], dtype=np.int64)
    assert oracle_ahead.kernel_signature() == (typeof(b), typeof(as_obs(obs)), typeof(K.allocate_state(B, M, N)),
                                               typeof(hp[2]), typeof(p[b]), typeof(t[b]))


ROLL_COLD = """
import glob, os, pickle, sys
import numpy as np
from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.policies.kernels.forward import roll_forward
from wfbench.policies.oracle import ahead
from wfbench.scenarios.resolve import resolve_scenario

ahead.compile_kernels()  # what the second process does first
sim = Simulator(resolve_scenario("small").replace(horizon=4), [0], keep_series=False, threads=1)
sim.reset()
codes, hp, pstate = policies.get("solver-tuned").compiled_plan(np.array([0]), sim.M, sim.N)
roll_forward(sim, 2, codes, hp, pstate)  # the every-rule roll-forward, compiled here from scratch
counts = {}
for k in ahead.KERNELS:
    name = k.py_func.__qualname__
    for f in glob.glob(os.path.join(os.environ["WFBENCH_CACHE_DIR"], "**", f"*.{name}-*.nbi"), recursive=True):
        with open(f, "rb") as fh:
            pickle.load(fh)
            counts[name] = len(pickle.loads(fh.read())[1])
print(counts)
"""


@pytest.mark.slow
def test_the_roll_forward_loads_the_kernels_the_job_compiled(tmp_path):
    """Cold: after the job's kernels, compiling the every-rule roll-forward adds no other signature of them."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "WFBENCH_CACHE_DIR": str(tmp_path / "wfbench"), "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "NUMBA_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", ROLL_COLD], env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    counts = eval(out.stdout.strip().splitlines()[-1])
    assert counts == {"positioning_facility": 1, "positioning_facility_sparse": 1}


# -- the oracle's network candidates: played on the other core, their totals handed back ------------------
NETWORKS = ["random", "heuristic", "ppo-joint", "ppo-dispatch", "hindsight-joint"]
LOOKUP = totals_cache.lookup  # the totals cache's own read


def _networks_play(seeds=(0, 1)):
    oracle = BestInHindsight(NETWORKS, policies.get)
    result = run_batch(LoadedPolicy(oracle, "oracle", None), SHORT, list(seeds), threads=1)
    return oracle, result


@pytest.mark.slow
def test_the_networks_played_there_are_the_networks_played_here(started, oracle_totals, monkeypatch):
    """Some networks' totals come from the second process; the oracle's choice, scores and episodes do not move."""
    import os
    import time

    real = oracle_ahead.claim

    def after_theirs(claims, key):  # here only: this process lets the second one claim a candidate first
        deadline = time.monotonic() + 300
        while os.path.isdir(claims) and not os.listdir(claims) and time.monotonic() < deadline:
            time.sleep(0.05)
        return real(claims, key)

    monkeypatch.setattr(oracle_ahead, "claim", after_theirs)
    played = _networks_play()
    assert len(started) == 4 and None not in started  # the kernels, the step, the rules, the networks
    assert isinstance(started[-1].result(timeout=300), float)
    there = [n for n in NETWORKS[2:] if played[0].cached.get(n)]
    assert there, "the second process handed back no network's totals: the check would be empty"
    deadline = time.monotonic() + 30  # the job's callbacks may run a moment after its result is seen
    while totals_cache.lookup is not LOOKUP and time.monotonic() < deadline:
        time.sleep(0.05)
    assert totals_cache.lookup is LOOKUP, "the wait on the totals cache outlived the job"
    assert not list((oracle_totals / "claims").iterdir()), "the claims' folder outlived the job"
    assert played[1].cpu_s > 0
    monkeypatch.setattr(runner, "compile_ahead", lambda *args, **kwargs: None)  # no second process at all
    monkeypatch.setenv(totals_cache.ENV, "off")
    _same(played, _networks_play())


def test_whoever_claims_a_candidate_first_plays_it(tmp_path):
    claims = str(tmp_path)
    assert oracle_ahead.claim(claims, "k1")  # the first claim
    assert not oracle_ahead.claim(claims, "k1")  # the other process's: it waits or stops
    assert oracle_ahead.claim(str(tmp_path / "gone"), "k1")  # the job's folder removed: nobody else plays it


def test_a_miss_on_a_claimed_network_waits_for_its_totals(oracle_totals):
    from concurrent.futures import Future

    seeds = np.array([3, 4])
    keys = totals_cache.batch_keys(seeds)
    claims = oracle_totals.parent / "claims"
    claims.mkdir()
    oracle_ahead.claim(str(claims), "theirs")  # the second process plays this one
    future = Future()
    real = totals_cache.lookup
    oracle_ahead.wait_on_totals(["theirs", "mine"], str(claims), future, limit_s=30)
    _, found = totals_cache.lookup("mine", seeds, keys)
    assert not found.any() and (claims / "mine").exists()  # unclaimed: this process claims it and plays it
    threading.Timer(0.3, totals_cache.store, ("theirs", seeds, keys, np.array([1.5, 2.5]))).start()
    total, found = totals_cache.lookup("theirs", seeds, keys)  # claimed there: waits for the totals
    assert found.all() and total.tolist() == [1.5, 2.5]
    assert not future.done() and totals_cache.lookup is not real
    future.set_result(0.0)
    assert totals_cache.lookup is real and not claims.exists()  # undone with the job, the claims removed


def test_a_failed_network_job_leaves_the_play_here(oracle_totals):
    from concurrent.futures import Future

    seeds = np.array([3])
    claims = oracle_totals.parent / "claims"
    claims.mkdir()
    oracle_ahead.claim(str(claims), "theirs")
    future = Future()
    oracle_ahead.wait_on_totals(["theirs"], str(claims), future, limit_s=30)
    threading.Timer(0.2, future.set_exception, (RuntimeError("the job failed"),)).start()
    _, found = totals_cache.lookup("theirs", seeds, totals_cache.batch_keys(seeds))
    assert not found.any()  # no exception here: the oracle plays it itself


def test_no_network_job_where_the_totals_cache_is_off_or_the_oracle_replays(monkeypatch):
    oracle = BestInHindsight(NETWORKS, policies.get)
    oracle.attach(SHORT)
    oracle.compile_ahead(lambda dispatcher: False)
    assert oracle_ahead.network_keys(oracle) == {}  # the autouse fixture turned the cache off
    monkeypatch.delenv(totals_cache.ENV)
    assert list(oracle_ahead.network_keys(oracle)) == NETWORKS[2:]  # the networks, in the oracle's order
    replaying = BestInHindsight(NETWORKS, policies.get, replay=True)
    replaying.attach(SHORT)
    replaying.compile_ahead(lambda dispatcher: False)
    assert oracle_ahead.network_keys(replaying) == {}
