"""``wfbench bench``: env-steps per second of the core and of the environment shells.

Measures, after a warm-up run that loads the compiled code:

- the compiled rollout with the heuristic policy in the loop, B = 1, 64, 1024, on one
  thread and on all cores: whole episodes (reset, observe, act, step) of a batch whose
  traces are already built;
- ``evaluate.run_batch`` end to end at B = 1024 on all cores: the same plus building
  the 1,024 traces and the state in Python;
- the Python batched loop (``Simulator.step`` + ``policy.act``), B = 64;
- PettingZoo ``parallel_env().step()`` and Gymnasium ``step()`` with random actions. The
  actions are sampled from the action spaces before the clock starts (1,000 of them,
  cycled), so the rate is the environment's, not gymnasium's sampler's.

Prints the machine and one line per measurement; ``--json`` writes them to a file.

Every run also times two fixed loops, one in Python and one compiled, before and after
the measurements. They do the same work on every machine and every run, so they show
the machine's speed at the time: on a shared virtual machine it drifts (by up to 2.5x
minute to minute on the development VM), and two runs compare only when their
reference times do.
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numba
import numpy as np

from wfbench.config import ScenarioConfig


def machine() -> dict[str, str | int]:
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count() or 1, "python": platform.python_version(),
            "numpy": np.__version__, "numba": numba.__version__, "platform": platform.platform()}


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
    from policies import get
    from policies.rollout import rollout
    from wfbench.evaluate import run_batch
    from wfbench.simulator import Simulator

    run_batch("heuristic", config, [0], threads=1)  # warm-up (loads compiled code)
    seeds = list(range(B))
    sim = Simulator(config, seeds, keep_series=False)
    best = float("inf")
    for _ in range(repeats):
        # every episode starts with its reset; the policy state is a fresh one each time
        codes, hp, pstate = get("heuristic").compiled_plan(seeds, sim.M, sim.N)
        t0 = time.perf_counter()
        rollout(sim, codes, hp, pstate, threads)
        best = min(best, time.perf_counter() - t0)
    return B * config.horizon / best


def _run_batch_rate(config: ScenarioConfig, B: int, repeats: int) -> float:
    from wfbench.evaluate import run_batch

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_batch("heuristic", config, list(range(B)))
        best = min(best, time.perf_counter() - t0)
    return B * config.horizon / best


def _python_loop_rate(config: ScenarioConfig, B: int) -> float:
    from policies import get
    from wfbench.simulator import Simulator

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


def run(scenario: str = "paper-64", quick: bool = False, json_path: str | None = None) -> list[dict]:
    config = ScenarioConfig.resolve(scenario)
    info = machine()
    print(f"machine: {info['cpu']}, {info['cores']} cores, Python {info['python']}, numpy {info['numpy']}, "
          f"numba {info['numba']}")
    print(f"scenario: {config.name} (horizon {config.horizon})")
    rows: list[dict] = []
    references = []

    def reference(when: str) -> None:
        r = reference_times()
        references.append({"when": when, **r})
        print(f"  machine speed {when}: Python loop {r['python_loop_s']:.3f} s, compiled loop "
              f"{r['compiled_loop_s']:.3f} s (fixed work; lower is faster)", flush=True)

    reference("before")

    def report(name: str, rate: float) -> None:
        rows.append({"measurement": name, "env_steps_per_s": rate})
        print(f"  {name:<48s} {rate:>14,.0f} env-steps/s", flush=True)

    cores = numba.config.NUMBA_NUM_THREADS
    sizes = (1, 64) if quick else (1, 64, 1024)
    for B in sizes:
        report(f"compiled rollout, heuristic, B={B}, 1 thread", _rollout_rate(config, B, 1, 1 if quick else 3))
        if cores > 1 and B > 1:
            report(f"compiled rollout, heuristic, B={B}, {cores} threads",
                   _rollout_rate(config, B, cores, 1 if quick else 3))
    if not quick and cores > 1:
        report(f"evaluate.run_batch end to end (traces built), B=1024, {cores} threads",
               _run_batch_rate(config, 1024, 3))
    report("Simulator.step + policy.act, heuristic, B=64", _python_loop_rate(config, 64))
    report("PettingZoo parallel_env.step, random actions", _pettingzoo_rate(config, 500 if quick else 3000))
    report("Gymnasium Workforce-v0 step, random actions", _gym_rate(config, 500 if quick else 3000))
    reference("after")
    if json_path:
        Path(json_path).write_text(json.dumps({"machine": info, "scenario": config.name, "results": rows,
                                               "reference": references}, indent=2))
    return rows
