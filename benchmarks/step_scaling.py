"""The cost of one env-step against the size of the world, up to suite-v1's city scenario (issues #27, #35).

For each scenario, on one thread (``threads=1``, so the numbers are per core):

- ``sim``: the simulator alone, ``Simulator.step`` with the no-op action (nobody dispatched,
  hired or let go), over whole episodes of B environments: the floor every policy pays;
- ``heuristic``, ``solver`` and ``solver-sparse``: the compiled rollout of the built-in composite
  (``wfbench.harness.runner.run_batch``), simulator and decisions together, whole episodes;
  ``solver-sparse`` is ``solver`` with its assignment and p-median on sparse candidate
  graphs (the k nearest; docs/solvers.md, "Sparse candidate graphs").

Beside the presets, ``city-1024`` is ``city`` in a 1024 x 1024 grid with 1,000 facility slots
and 800 people slots (``ScenarioConfig.replace``; same start, 500 + 500), the world of
issue #35's scaling goal.

It prints, per scenario, the slots and the people and facilities at the start, then the
env-steps per second and the microseconds per env-step of each row (best of
``--rounds``), and the machine. Usage::

    python benchmarks/step_scaling.py --rounds 2 --seeds 4 --json step-scaling.json
    python benchmarks/step_scaling.py --rounds 1 --seeds 2 --scenarios large,city,city-1024 --rows solver,solver-sparse
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import machine, machine_line
from wfbench.harness.runner import run_batch

SCENARIOS = ["small", "paper-64", "large", "city", "city-1024"]
ROWS = ["sim", "heuristic", "solver", "solver-sparse"]


def scenario(name: str) -> ScenarioConfig:
    """A preset, or ``city-1024``: city in a 1024 x 1024 grid with 1,000 facility and 800 people slots."""
    if name == "city-1024":
        return ScenarioConfig.preset("city").replace(grid_width=1024, grid_height=1024, max_facilities=1000,
                                                     max_personnel=800)
    return ScenarioConfig.preset(name)


def _noop(sim: Simulator) -> dict[str, np.ndarray]:
    """The do-nothing action of every decision, shaped like ``wfbench.core.actions`` lays it out."""
    B, c = sim.B, sim.config
    return {"dispatch": np.full((B, c.max_facilities), c.max_personnel, dtype=np.int64),
            "workforce": np.zeros(B, dtype=np.int64),
            "positioning": np.zeros((B, 2, c.max_facilities), dtype=np.float64)}


def time_sim(config: ScenarioConfig, seeds: list[int]) -> float:
    sim = Simulator(config, seeds, keep_series=False)
    sim.reset()
    action = _noop(sim)
    t0 = time.perf_counter()
    for _ in range(config.horizon):
        sim.step(action)
    return time.perf_counter() - t0


def time_policy(name: str, config: ScenarioConfig, seeds: list[int]) -> float:
    t0 = time.perf_counter()
    run_batch(name, config, seeds, threads=1)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2, help="measure each row this many times, keep the best")
    ap.add_argument("--seeds", type=int, default=4, help="environments per batch (seeds 0..N-1)")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--rows", default=",".join(ROWS), help="which of " + ", ".join(ROWS))
    ap.add_argument("--json", default=None, help="also write the rows to this file")
    args = ap.parse_args()
    seeds = list(range(args.seeds))
    print(f"machine: {machine_line(machine())}; load {os.getloadavg()[0]:.2f}; one thread; B = {len(seeds)}",
          flush=True)
    rows = []
    for name in args.scenarios.split(","):
        config = scenario(name)
        steps = config.horizon * len(seeds)
        for kind in args.rows.split(","):
            def run(kind: str = kind, config: ScenarioConfig = config) -> float:
                return time_sim(config, seeds) if kind == "sim" else time_policy(kind, config, seeds)

            run()  # warm-up: compiled code loaded, caches filled
            best = min(run() for _ in range(args.rounds))
            row = {"scenario": name, "slots": config.max_facilities + config.max_personnel,
                   "start": config.initial_facilities + config.initial_personnel, "row": kind,
                   "env_steps_per_s": steps / best, "us_per_env_step": 1e6 * best / steps}
            rows.append(row)
            print(f"{name:10s} slots {row['slots']:5d} start {row['start']:5d} {kind:13s} "
                  f"{row['env_steps_per_s']:12,.0f} env-steps/s {row['us_per_env_step']:10.1f} us/env-step", flush=True)
    print(f"load at the end {os.getloadavg()[0]:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"machine": machine(), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
