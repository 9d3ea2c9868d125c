"""``wfbench bench``: env-steps per second of the core and of the environment shells.

After a warm-up run, it measures the compiled rollout (heuristic, B = 1, 64, 1024, one thread
and all cores), ``run_batch`` end to end, ``Simulator.step_observe``, the Python batched loop and
the PettingZoo and Gymnasium ``step``, with actions drawn before the clock starts. Rounds are
interleaved (``--rounds``) and each row reports its best, median and worst round; ``--json``
writes them to a file. Two fixed reference loops, timed before and after, show the machine's
speed at the time, so two runs compare only when their reference times do. How it measures and
the numbers: ``docs/performance.md``, "wfbench bench".
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numba
import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.harness.budget import machine  # the machine record every result row carries
from wfbench.scenarios.resolve import resolve_scenario


@numba.njit(cache=True)
def _reference_kernel(n):
    """A fixed integer loop (xorshift64, a serial chain the compiler cannot shortcut), compiled."""
    x = np.uint64(88172645463325252)
    for _ in range(n):
        x ^= x << np.uint64(13)
        x ^= x >> np.uint64(7)
        x ^= x << np.uint64(17)
    return x


def reference_times() -> dict[str, float]:
    """Seconds for a fixed pure-Python loop (3M additions) and a fixed compiled loop (40M steps), best of 3."""
    _reference_kernel(10)
    python = compiled = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        total = 0
        for i in range(3_000_000):
            total += i
        python = min(python, time.perf_counter() - t0)
        t0 = time.perf_counter()
        _reference_kernel(40_000_000)
        compiled = min(compiled, time.perf_counter() - t0)
    return {"python_loop_s": python, "compiled_loop_s": compiled}


def _rollout_rate(config: ScenarioConfig, B: int, threads: int, repeats: int) -> float:
    from wfbench.core.simulator import Simulator
    from wfbench.policies import get
    from wfbench.policies.episode import play_episodes

    seeds = list(range(B))
    sim = Simulator(config, seeds, keep_series=False)
    best = float("inf")
    for _ in range(repeats):
        # every episode starts with its reset; the policy state is a fresh one each time
        codes, hp, pstate = get("heuristic").compiled_plan(seeds, sim.M, sim.N)
        t0 = time.perf_counter()
        play_episodes(sim, codes, hp, pstate, threads)
        best = min(best, time.perf_counter() - t0)
    return B * config.horizon / best


def _run_batch_rate(config: ScenarioConfig, B: int, repeats: int) -> float:
    from wfbench.harness.runner import run_batch

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_batch("heuristic", config, list(range(B)))
        best = min(best, time.perf_counter() - t0)
    return B * config.horizon / best


def _step_observe_rate(config: ScenarioConfig, B: int, threads: int, repeats: int, steps: int = 50) -> float:
    """``Simulator.step_observe`` on ``threads`` threads, random actions drawn before the clock."""
    from wfbench.core.simulator import Simulator

    sim = Simulator(config, list(range(B)), keep_series=False, threads=threads)
    rng = np.random.default_rng(0)
    actions = [{"dispatch": rng.integers(0, sim.N + 1, size=(B, sim.M), dtype=np.int64),
                "workforce": rng.integers(0, 7, size=B, dtype=np.int64),
                "positioning": rng.random((B, 2, sim.M))} for _ in range(8)]
    sim.reset()
    for a in actions[:3]:  # loads the compiled step
        sim.step_observe(a)
    best = float("inf")
    for _ in range(repeats):
        sim.reset()
        t0 = time.perf_counter()
        for i in range(steps):
            sim.step_observe(actions[i % len(actions)])
        best = min(best, time.perf_counter() - t0)
    return B * steps / best


def _python_loop_rate(config: ScenarioConfig, B: int) -> float:
    from wfbench.core.simulator import Simulator
    from wfbench.policies import get

    policy = get("heuristic")
    sim = Simulator(config, list(range(B)), keep_series=False)
    obs = sim.reset()
    policy.reset(sim.seeds)
    for _ in range(5):
        sim.step(policy.act(obs))
        obs = sim.observe()
    t0 = time.perf_counter()
    steps = 0
    while not sim.done and steps < 300:
        sim.step(policy.act(obs))
        obs = sim.observe()
        steps += 1
    return B * steps / (time.perf_counter() - t0)


def _pettingzoo_rate(config: ScenarioConfig, steps: int) -> float:
    from wfbench.envs.parallel import parallel_env

    env = parallel_env(config)
    env.reset(seed=0)
    for a in env.agents:
        env.action_space(a).seed(0)
    actions = [{a: env.action_space(a).sample() for a in env.agents} for _ in range(1000)]
    for i in range(100):  # warm-up
        env.step(actions[i])
    env.reset(seed=0)
    t0 = time.perf_counter()
    for i in range(steps):
        if not env.agents:
            env.reset()
        env.step(actions[i % len(actions)])
    return steps / (time.perf_counter() - t0)


def _gym_rate(config: ScenarioConfig, steps: int) -> float:
    from wfbench.envs.gym_env import WorkforceEnv

    env = WorkforceEnv(config)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(1000)]
    for i in range(100):  # warm-up
        env.step(actions[i])
    env.reset(seed=0)
    t0 = time.perf_counter()
    for i in range(steps):
        _, _, term, trunc, _ = env.step(actions[i % len(actions)])
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t0)


def run(scenario: str | ScenarioConfig = "paper-64", quick: bool = False, json_path: str | None = None,
        rounds: int | None = None) -> list[dict]:
    """Measure every row ``rounds`` times (default 3, 1 with ``quick``), the rows interleaved.

    A round runs each measurement once, so a slow spell of the machine hits every row a
    little instead of one row entirely. Each row reports its best, median and worst
    round; the best is the machine's speed when nothing else got in the way, the spread
    is how much it drifted. ``scenario`` is a scenario name
    (:func:`wfbench.scenarios.resolve.resolve_scenario`) or a :class:`ScenarioConfig`.
    """
    from wfbench.harness.runner import run_batch

    config = resolve_scenario(scenario)
    rounds = (1 if quick else 3) if rounds is None else rounds
    if rounds < 1:
        raise ValueError(f"rounds = {rounds} is not allowed; allowed: an integer >= 1")
    info = machine()
    print(f"machine: {info['cpu']}, {info['cores']} cores, Python {info['python']}, numpy {info['numpy']}, "
          f"numba {info['numba']}")
    print(f"scenario: {config.name} (horizon {config.horizon}), {rounds} round(s)")
    references = []

    def reference(when: str) -> None:
        r = reference_times()
        references.append({"when": when, **r})
        print(f"  machine speed {when}: Python loop {r['python_loop_s']:.3f} s, compiled loop "
              f"{r['compiled_loop_s']:.3f} s (fixed work; lower is faster)", flush=True)

    cores = numba.config.NUMBA_NUM_THREADS
    repeats = 1 if quick else 3
    plan = []
    for B in (1, 64) if quick else (1, 64, 1024):
        plan.append((f"compiled rollout, heuristic, B={B}, 1 thread",
                     lambda B=B: _rollout_rate(config, B, 1, repeats)))
        if cores > 1 and B > 1:
            plan.append((f"compiled rollout, heuristic, B={B}, {cores} threads",
                         lambda B=B: _rollout_rate(config, B, cores, repeats)))
    if not quick and cores > 1:
        plan.append((f"evaluate.run_batch end to end (traces built), B=1024, {cores} threads",
                     lambda: _run_batch_rate(config, 1024, repeats)))
    step_b = 64 if quick else 1024
    plan.append((f"Simulator.step_observe, random actions, B={step_b}, 1 thread",
                 lambda: _step_observe_rate(config, step_b, 1, repeats)))
    if cores > 1:
        plan.append((f"Simulator.step_observe, random actions, B={step_b}, {cores} threads",
                     lambda: _step_observe_rate(config, step_b, cores, repeats)))
    plan.append(("Simulator.step + policy.act, heuristic, B=64", lambda: _python_loop_rate(config, 64)))
    env_steps = 500 if quick else 3000
    plan.append(("PettingZoo parallel_env.step, random actions", lambda: _pettingzoo_rate(config, env_steps)))
    plan.append(("Gymnasium Workforce-v0 step, random actions", lambda: _gym_rate(config, env_steps)))

    width = max(len(name) for name, _ in plan)
    run_batch("heuristic", config, [0], threads=1)  # loads (or compiles) the rollout once, before any clock
    reference("before")
    measured: dict[str, list[float]] = {name: [] for name, _ in plan}
    for r in range(rounds):
        if rounds > 1:
            print(f"  round {r + 1} of {rounds}", flush=True)
        for name, measure in plan:
            measured[name].append(measure())
            print(f"    {name:<{width}s} {measured[name][-1]:>12,.0f} env-steps/s", flush=True)
    reference("after")
    rows = [{"measurement": name, "env_steps_per_s": max(v), "median": float(np.median(v)), "worst": min(v),
             "rounds": v} for name, v in measured.items()]
    if rounds > 1:
        print(f"  {'env-steps/s over the rounds':<{width + 2}s} {'best':>12s} {'median':>12s} {'worst':>12s}")
        for row in rows:
            print(f"  {row['measurement']:<{width + 2}s} {row['env_steps_per_s']:>12,.0f} {row['median']:>12,.0f} "
                  f"{row['worst']:>12,.0f}")
    if json_path:
        Path(json_path).write_text(json.dumps({"machine": info, "scenario": config.name, "rounds": rounds,
                                               "results": rows, "reference": references}, indent=2))
    return rows
