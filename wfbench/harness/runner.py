"""One batch of full episodes, and the per-seed result rows.

:func:`run_batch` runs every seed of a chunk as one batch: a composite of built-in kernels
through the compiled episode runner (:mod:`wfbench.policies.episode`), any other policy
through a batched ``reset`` / ``act`` / ``step`` loop (a user's
through its :class:`~wfbench.harness.guard.Guard`). A policy with ``reads_trace = True`` gets
``attach(config)`` before ``reset``; one with ``set_world`` gets :func:`public_world` (the laws of
the world, no seed or trace). A compiled run of a registry name leaves its NSW totals in the
oracle's totals cache, and one of any other candidate of a replaying reference its episodes
(:class:`~wfbench.policies.oracle.replay.Recorder`). A batch also measures its cost (:mod:`wfbench.harness.budget`).
:func:`results_frame` makes one row per seed. ``docs/hindsight.md``; ``docs/policies.md``, "The
world's public parameters: set_world".
"""

from __future__ import annotations

import copy
import functools
import os
import sys
import threading
import time
import weakref
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from joblib.externals.loky import ProcessPoolExecutor
from numba.core import event as numba_event

from wfbench.core import jit
from wfbench.core.config import ScenarioConfig
from wfbench.core.dynamics import apply_workforce
from wfbench.core.observe import step_range
from wfbench.core.simulator import Simulator
from wfbench.core.state import COUNTERS, INVALID_COUNTERS, METRICS
from wfbench.harness.budget import machine
from wfbench.harness.guard import LoadedPolicy, load_policy
from wfbench.policies import Composite
from wfbench.policies.episode import play_episodes
from wfbench.policies.lookahead.ahead import rollout_job
from wfbench.policies.oracle import cache as totals_cache
from wfbench.policies.oracle.ahead import HERE as ORACLE_HERE
from wfbench.policies.oracle.ahead import HERE_S as ORACLE_HERE_S
from wfbench.policies.oracle.ahead import network_jobs, oracle_job

K_NSW = METRICS.index("nsw")


def public_world(config: ScenarioConfig) -> ScenarioConfig:
    """What ``set_world`` is handed: the world's public parameters, a copy of the scenario's config.

    A :class:`ScenarioConfig` holds the laws of a world (rates and their schedules, the
    layout's kind and parameters, delays, salaries, slots) and nothing drawn for an episode:
    the seeds, their keys and the trace (the arrivals, clocks and towns drawn per seed) are
    not fields of it. The copy goes through the config's own dict, so a policy that changes
    it changes nothing of the evaluator's.
    """
    return ScenarioConfig.from_dict(config.to_dict())


@dataclass
class BatchResult:
    """The finished episodes of one batch, row ``i`` for ``seeds[i]``."""

    seeds: list[int]
    means: dict[str, np.ndarray]  # metric -> (B,) episode mean
    counters: dict[str, np.ndarray]  # counter -> (B,) int
    steps: np.ndarray  # (B,) steps run
    series: np.ndarray | None  # (B, horizon, len(METRICS)) float32
    decision_ms: tuple[float, float] = (float("nan"), float("nan"))  # p50, p99 ms per decision of one environment
    cpu_s: float = float("nan")  # CPU seconds of the process per episode
    timing: str = ""  # "act" (each act call timed) or "rollout" (a compiled rollout's time per environment-step)
    machine: dict[str, Any] = field(default_factory=dict)  # where the batch ran (wfbench.harness.budget.machine)


class _CompileClock(numba_event.Listener):
    """Wall and CPU seconds numba held its compiler lock (loading from its cache or compiling) while installed.

    Both clocks: on a busy machine a compile's wall time exceeds its CPU time, and each
    is subtracted from a measurement on the same clock.
    """

    def __init__(self) -> None:
        self.depth = 0
        self.wall = self.cpu = 0.0
        self.w0 = self.c0 = 0.0

    def on_start(self, event: numba_event.Event) -> None:
        if self.depth == 0:
            self.w0, self.c0 = time.perf_counter(), time.process_time()
        self.depth += 1

    def on_end(self, event: numba_event.Event) -> None:
        self.depth -= 1
        if self.depth == 0:
            self.wall += time.perf_counter() - self.w0
            self.cpu += time.process_time() - self.c0


@contextmanager
def _compile_clock() -> Iterator[_CompileClock]:
    clock = _CompileClock()
    with numba_event.install_listener("numba:compiler_lock", clock):
        yield clock


def run_batch(policy: Any, config: ScenarioConfig, seeds: Sequence[int], keep_series: bool = False,
              threads: int | None = None) -> BatchResult:
    """Run full episodes of ``seeds`` as one batch.

    Args:
        policy: a :class:`~wfbench.harness.guard.LoadedPolicy` (what the backends pass: resolved
            once per evaluation), or anything :func:`~wfbench.harness.guard.load_policy` takes,
            loaded here with the default act timeout.
        config: the scenario, resolved (a name is resolved by :class:`Simulator` only, at its edge).
        seeds: one environment per seed.
        keep_series: also keep the per-step metrics.
        threads: numba threads of the compiled episode runner (default: all cores).

    Returns:
        The batch's episode means, counters and steps (and series).

    Raises:
        wfbench.harness.guard.PolicyError: a user's policy raised, hung past its act timeout or
            returned a malformed action.
    """
    loaded = load_policy(policy)
    policy, guard = loaded.policy, loaded.guard
    with _compile_clock() as compiling:
        cpu0 = time.process_time()
        sim = Simulator(config, seeds, keep_series=keep_series)
        per_step: list[float] = []  # ms per decision of one environment, one entry per act call
        recording = 0.0  # CPU s of recording the episodes for the oracle (:func:`_recorder`)
        ahead: list = []  # the second process's jobs (cold only)
        played_there = 0.0  # CPU s of the policy's own work done there (the oracle's network candidates)

        def timed(act: Any, obs: Any) -> Any:
            c0, t0 = compiling.wall, time.perf_counter()
            out = act(obs)
            per_step.append((time.perf_counter() - t0 - (compiling.wall - c0)) * 1e3 / sim.B)
            return out

        if isinstance(policy, Composite) and policy.compiled:
            codes, hp, pstate = policy.compiled_plan(seeds, sim.M, sim.N)
            keys = pstate.keys.copy()  # before the episode, for the totals cache
            c0, r0 = compiling.cpu, time.process_time()
            play_episodes(sim, codes, hp, pstate, threads)
            # one compiled call: its CPU time over the environment-steps it ran (wfbench.harness.budget)
            cpu = max(0.0, time.process_time() - r0 - (compiling.cpu - c0))
            step_ms = cpu * 1e3 / max(1, int(sim.state.t.sum()))
            decision_ms, timing = (step_ms, step_ms), "rollout"
        else:
            if guard is None:  # a built-in: our own code runs as it is
                if getattr(policy, "reads_trace", False):  # a hindsight oracle: handed the scenario, so the future
                    policy.attach(sim.config)
                elif hasattr(policy, "set_world"):  # a deployable policy that asks for the public parameters
                    policy.set_world(public_world(sim.config))
                # cold: part compiles on the other core, the step from now on, while this process compiles the reset
                ahead = start_compile_ahead(policy, sim.config, keep_series, seeds)
            obs = sim.reset()
            if guard is None:
                r0 = time.process_time()  # the recording is the oracle's, not the policy's: its CPU is left out
                record = _recorder(loaded.name, sim, seeds)
                recording += time.process_time() - r0
                policy.reset(sim.seeds)
                while not sim.done:
                    action = timed(policy.act, obs)
                    if record is not None:
                        r0 = time.process_time()
                        record.add(sim.t, action)
                        recording += time.process_time() - r0
                    sim.step(action)
                    obs = sim.observe()
                if record is not None:
                    r0 = time.process_time()
                    record.store(sim.state.totals[:, K_NSW].astype(np.float64))
                    recording += time.process_time() - r0
            else:
                if getattr(policy, "reads_trace", False):  # declared: the leaderboard keeps it off deployable tracks
                    guard.call("attach", policy.attach, sim.config)
                elif hasattr(policy, "set_world"):  # a sandbox passes it on with RESET (isolation.child.serve)
                    guard.call("set_world", policy.set_world, public_world(sim.config))
                guard.call("reset", policy.reset, sim.seeds)
                while not sim.done:
                    guard.step(sim, timed(lambda o: guard.call("act", policy.act, o), obs), policy.act)
                    obs = sim.observe()
                played_there = _played_there(ahead)  # the oracle's episodes played by the second process
            q = np.percentile(per_step, [50, 99]) if per_step else (float("nan"), float("nan"))
            decision_ms, timing = (float(q[0]), float(q[1])), "act"
        cpu_s = max(0.0, time.process_time() - cpu0 - compiling.cpu - recording + played_there) / max(1, len(seeds))
    if guard is None:  # a registry name: the oracle plays it as a candidate and reuses these
        totals = sim.state.totals[:, K_NSW].astype(np.float64)
        if timing == "rollout":
            totals_cache.store(totals_cache.policy_key(sim.config, codes, hp), np.asarray(seeds), keys, totals)
        elif (key := totals_cache.played_key(sim.config, policy)) is not None:  # a shipped network, on this batch
            totals_cache.store(key, np.asarray(seeds), totals_cache.batch_keys(np.asarray(seeds)), totals)
    return BatchResult(
        seeds=list(seeds), means=sim.episode_means(), counters=sim.counters(), steps=sim.state.t.copy(),
        series=sim.state.series.copy() if keep_series else None, decision_ms=decision_ms, cpu_s=cpu_s,
        timing=timing, machine=machine(),
    )


def _recorder(name: str, sim: Simulator, seeds: Sequence[int]) -> Any:
    """A recorder of ``name``'s episodes where a replaying reference reads them (and the store is on), else None.

    :class:`~wfbench.policies.oracle.replay.Recorder`: what is played here is not played there again.
    """
    from wfbench.policies.oracle.references import replayed

    if name not in replayed() or not totals_cache.enabled():
        return None
    from wfbench.policies import get
    from wfbench.policies.oracle.replay import Recorder

    return Recorder(sim.config, name, get(name), seeds, sim.M, sim.N)


def prime(loaded: LoadedPolicy, config: ScenarioConfig) -> None:
    """Compile (or load from numba's cache) what :func:`run_batch` will run for ``loaded`` on ``config``.

    A two-step episode of one seed on ``config``'s shapes: the compiled episodes of a
    built-in composite, a built-in policy's own loop, or for a user's policy (whose code
    does not run here) the simulator's reset, step and observe with empty actions. The
    process and Ray backends call it before starting their workers, so that on a cold
    cache the core compiles once, here, and the workers load it from disk instead of
    each compiling the same code (and printing the notice) at the same time. On a warm
    cache it only loads: about 0.1 s for the simulator, 0.4 s for the compiled episode runner.
    """
    short = config.replace(horizon=2)
    if loaded.guard is None:
        # on a copy: playing leaves state on a policy (an oracle's planner holds compiled closures), and the
        # workers are sent the untouched one, which must still pickle
        run_batch(copy.deepcopy(loaded), short, [0], threads=1)
        return
    step_once(short)


# -- compiling in a second process -----------------------------------------------------------------
def has_entries(dispatcher) -> bool:
    """Whether numba's on-disk cache holds a compilation of ``dispatcher`` (any signature) for this machine.

    Reads the cache's index as numba does before compiling (an index whose source stamp is not
    the current digest, ``wfbench.core.jit``, reads as empty); False where it cannot be read.
    """
    try:
        index = dispatcher._cache._cache_file._load_index()
        magic = dispatcher.targetctx.codegen().magic_tuple()
    except Exception:  # no numba cache (cache=False, not a dispatcher), or numba's internals moved: cold
        return False
    return any(isinstance(key, tuple) and len(key) > 1 and key[1] == magic for key in index)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _quiet_child() -> None:
    """The second process prints and records nothing: the first process's lines speak for both."""
    numba_event.unregister("numba:compile", jit.NOTICE)


_AHEAD: dict = {"pool": None, "jobs": 0}  # the second process's pool while it has jobs, and how many
_AHEAD_LOCK = threading.Lock()  # also guards the waits of wait_on_miss


def compile_ahead(what: str, job: Any, *args: Any, waits: Sequence[Any] = (), announce: bool = True) -> Any:
    """Run ``job(*args)`` in a second process now, to compile into numba's on-disk cache what this one needs later.

    A numba compilation runs on one core; where there are two or more, the second process
    compiles (and caches: every function of ours is ``cache=True``) functions this process will
    call later while this one compiles others, and this one then loads them from disk. The job
    changes no number: it only compiles (running what it compiled on throw-away data), and this
    process compiles for itself whatever is not on disk when it needs it (the job failed, is not
    done yet, or there is one core). Jobs queue in one second process, a worker of loky's process
    pool (the process backend's: a script without a ``__main__`` guard works), which exits when
    they are done. Prints one line on stderr naming ``what``.

    ``waits``: the dispatchers the job compiles. Until it is done, this process, asked for one
    of them that is not on disk, waits for the job and reads the disk again instead of compiling
    it a second time (:func:`wait_on_miss`): the job started earlier, so it finishes first.

    Returns:
        The job's future (nothing waits for it unless a dispatcher of ``waits`` is asked for),
        or None where no second process was asked.
    """
    if _cores() < 2:
        return None
    try:
        with _AHEAD_LOCK:
            if _AHEAD["pool"] is None:
                _AHEAD["pool"] = ProcessPoolExecutor(max_workers=1, initializer=_quiet_child)
            pool = _AHEAD["pool"]
            future = pool.submit(job, *args)
            _AHEAD["jobs"] += 1
    except Exception:  # no second process: this one compiles everything itself, as without it
        return None
    future.add_done_callback(lambda _: _ahead_done(pool))
    for dispatcher in waits:
        wait_on_miss(dispatcher, future)
    if announce:
        announce_ahead([what])
    return future


def announce_ahead(whats: Sequence[str], here: tuple[str, float] | None = None) -> None:
    """The one line on stderr that says what the second process does, in its order, and what this one compiles.

    ``here``: what this process compiles meanwhile and its CPU seconds on an idle 2-core VM, scaled
    by the load as the cold-start line scales its own (:func:`wfbench.core.jit.load_factor`).
    """
    # "wfbench: compiling" like the line of jit.NOTICE, which scripts and tests set apart from a run's output
    line = (f"wfbench: compiling {', then '.join(whats)} in a second process meanwhile (on another core); "
            "cached afterwards")
    if here is not None:
        what, idle = here
        factor = jit.load_factor()
        cost = f"~{idle:.0f} s on an idle 2-core VM" if factor < 1.1 else \
            f"~{idle * factor:.0f} s ({idle:.0f} s on an idle 2-core VM, x{factor:.1f} for the current load)"
        line += f"; here meanwhile {what}, {cost}"
    print(line, file=sys.stderr, flush=True)


WAIT_LIMIT_S = 600.0  # the longest this process waits for a second process's job before it compiles for itself
POLL_S = 0.2  # how often a wait reads the disk again while the job runs
# what the step's job compiles that this process may ask for first: the step, and its workforce kernel, which a
# roll-forward inlines
STEP_WAITS = (step_range, apply_workforce)


def wait_on_miss(dispatcher: Any, future: Any, limit_s: float = WAIT_LIMIT_S) -> bool:
    """Until ``future`` is done, a compilation of ``dispatcher`` missing from disk waits for it to appear there.

    Numba reads its on-disk cache (``dispatcher._cache.load_overload``) before it compiles a
    signature, and reads the index afresh each time. Here that read, where it finds nothing
    while the job compiling ``dispatcher`` is still running, reads again every ``POLL_S``
    until the job has written it or is done (at most ``limit_s``): a job that compiles several
    functions hands each over as soon as it is cached, not at its end. What the job cached is
    loaded; anything else (another signature, a job that failed or is late) is compiled here
    as before. Nothing that runs changes, only where it is compiled. Undone after a wait that
    found nothing, or when the job is done. False where numba's internals differ (nothing is
    changed then).
    """
    try:
        cache = dispatcher._cache
        load = functools.partial(type(cache).load_overload, cache)  # numba's own read, not an earlier wait
    except AttributeError:
        return False

    def undo(_: Any = None) -> None:
        with _AHEAD_LOCK:
            if cache.__dict__.get("load_overload") is load_overload:
                del cache.__dict__["load_overload"]

    def load_overload(sig: Any, target_context: Any) -> Any:
        found = load(sig, target_context)
        deadline = time.monotonic() + limit_s
        while found is None and not future.done() and time.monotonic() < deadline:
            try:
                future.result(timeout=min(POLL_S, max(deadline - time.monotonic(), 0.0)))
            except TimeoutError:  # still running: it may have cached this one already
                pass
            except Exception:  # failed: compile here
                break
            found = load(sig, target_context)
        if future.done() or found is None:  # the job is over (or this one waited in vain): later reads are numba's own
            undo()
        return found

    cache.load_overload = load_overload
    # also when nobody missed: the future's callbacks may run after a waiter sees it done, so the wait undoes itself too
    future.add_done_callback(undo)
    return True


def _ahead_done(pool: Any) -> None:
    """A job of ``pool`` is done: after the last one its process exits (a later job starts another)."""
    with _AHEAD_LOCK:
        _AHEAD["jobs"] -= 1
        if _AHEAD["jobs"] or _AHEAD["pool"] is not pool:
            return
        _AHEAD["pool"] = None
    pool.shutdown(wait=False)


def start_compile_ahead(policy: Any, config: ScenarioConfig, keep_series: bool = False,
                        seeds: Sequence[int] | None = None) -> list:
    """On a cold cache, what a second process compiles while :func:`run_batch` plays a built-in ``policy``'s ``act``.

    The jobs queue in the order this process needs what they compile:

    - for a rollout, :func:`wfbench.policies.lookahead.ahead.rollout_job` first (its futures'
      roll-forward, while this process compiles its belief and base), then the step;
    - for a policy with a ``compile_ahead(has_entries)`` method (the oracles),
      :func:`wfbench.policies.oracle.ahead.oracle_job`'s two: their every-rule roll-forward's
      facility-location kernels first (this process compiles that roll-forward meanwhile and
      reaches them last of the rules), then the step (whose workforce kernel the roll-forward
      inlines at its end), then the built-in rules their candidates act with (their first live
      ``act``, after the roll-forward), and last, given the batch's ``seeds``, the oracle's network
      candidates' episodes (:func:`wfbench.policies.oracle.ahead.network_jobs`: played there
      from the last candidate while this process plays from the first, their totals handed back
      through the totals cache);
    - the simulator's step alone for any other, where it is not on disk (:func:`run_batch` asks
      before its reset: this process compiles the reset and the policy's own code first, and
      steps only after the first action).

    This process waits for what a job compiles rather than compile it again
    (:func:`wait_on_miss`). One line on stderr names what the jobs compile. Returns the futures
    started.
    """
    before: list[tuple] = []
    after: list[tuple] = []
    here = None  # what this process compiles meanwhile, for the line
    if callable(getattr(policy, "compile_ahead", None)):
        pair = oracle_job(policy, has_entries)
        if pair is not None:
            before, after, here = [pair[0]], [pair[1]], (ORACLE_HERE, ORACLE_HERE_S)
    else:
        job = rollout_job(policy, has_entries)
        before = [] if job is None else [job]
    step = [] if has_entries(step_range) else [("the simulator's step", step_once, (config, keep_series), STEP_WAITS)]
    jobs = before + step + after
    futures = [compile_ahead(what, fn, *args, waits=waits, announce=False) for what, fn, args, waits in jobs]
    started = [what for (what, *_), f in zip(jobs, futures, strict=True) if f is not None]
    if after and seeds is not None and None not in futures and (played := network_jobs(policy, seeds)) is not None:
        what, fn, args, start = played
        future = compile_ahead(what, fn, *args, announce=False)
        start(future)
        if future is not None:
            _PLAYING.add(future)
            futures.append(future)
            started.append(what)
    if started:
        announce_ahead(started, here)
    return [f for f in futures if f is not None]


_PLAYING: weakref.WeakSet = weakref.WeakSet()  # the futures of jobs that play the policy's episodes


def _played_there(futures: Sequence[Any], limit_s: float = 5.0) -> float:
    """The CPU seconds that the jobs of ``futures`` spent playing the policy's own episodes (the others compile).

    At the end of a batch such a job is done (this process waited for whatever it played); one
    that is late (``limit_s``) or failed counts nothing: what it did not hand back was played here.
    """
    cpu = 0.0
    for future in futures:
        if future not in _PLAYING:
            continue
        try:
            cpu += float(future.result(timeout=limit_s))
        except Exception:
            continue
    return cpu


def step_once(config: ScenarioConfig, keep_series: bool = True) -> None:
    """One seed of ``config``: reset, a step with empty actions, observe (compiles or loads the simulator core).

    What :func:`prime` runs for a user's policy, and what a second process runs on a cold
    cache while :func:`run_batch` plays a built-in policy through ``act``
    (:func:`start_compile_ahead`).
    """
    sim = Simulator(config.replace(horizon=2), [0], keep_series=keep_series)
    sim.reset()
    M, N = sim.M, sim.N
    sim.step({"dispatch": np.full((1, M), N), "workforce": np.zeros(1, dtype=np.int64),
              "positioning": np.ones((1, 2, M))})
    sim.observe()


def results_frame(results: Sequence[BatchResult], config: ScenarioConfig, policy_name: str) -> pd.DataFrame:
    """One row per seed of the batches, in batch order.

    The metrics, episode length and action counters, then the budget columns
    (``decision_ms_p50``, ``decision_ms_p99``, ``cpu_s``: the batch's measurements, the same
    for every seed of one batch).
    """
    rows = []
    for r in results:
        for i, seed in enumerate(r.seeds):
            row: dict[str, Any] = {"seed": seed}
            for k in METRICS:
                row[k] = float(r.means[k][i])
            row["episode_length"] = int(r.steps[i])
            for c in COUNTERS:
                row[c] = int(r.counters[c][i])
            row["invalid_actions"] = int(sum(r.counters[c][i] for c in INVALID_COUNTERS))
            row["decision_ms_p50"], row["decision_ms_p99"] = r.decision_ms
            row["cpu_s"] = r.cpu_s
            rows.append(row)
    df = pd.DataFrame(rows)
    df.attrs["scenario"] = config.name
    df.attrs["policy"] = policy_name
    return df
