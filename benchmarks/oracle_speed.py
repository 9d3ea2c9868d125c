"""Speed and score of the hindsight oracles (docs/hindsight.md, docs/performance.md).

Runs each policy over seeds 0..n-1 of a scenario, the seeds split into one batch per
worker process (what ``wfbench evaluate``'s process backend does), and prints:

- the wall time of each policy, and for the oracles the time per decision step and its
  split (shadow upkeep and check, base kernels, workforce and positioning look-ahead,
  dispatch look-ahead) with the number of roll-forwards;
- the NSW of every policy with its bootstrap interval, and the paired difference of
  each policy against each ``--against`` policy (``wfbench.analysis.stats``).

Until the runner attaches trace-reading policies itself, the oracles run through the
local loop ``attach(config); reset(seeds); act/step``, which is what the runner does
for a built-in policy.

Usage::

    python benchmarks/oracle_speed.py --scenario paper-64 --seeds 50 --workers 2 \\
        --policies oracle-planner,oracle-dispatch,solver,heuristic --against solver,heuristic
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import time

import numpy as np

from wfbench import policies
from wfbench.scenarios.resolve import resolve_scenario


def run_chunk(args):
    name, scenario, seeds = args
    from wfbench import Simulator

    config = resolve_scenario(scenario)
    pol = policies.get(name)
    start = time.perf_counter()
    if getattr(pol, "reads_trace", False):
        pol.attach(config)
    sim = Simulator(config, seeds, keep_series=False)
    obs = sim.reset()
    pol.reset(sim.seeds)
    while not sim.done:
        sim.step(pol.act(obs))
        obs = sim.observe()
    wall = time.perf_counter() - start
    timing = {}
    for part in getattr(pol, "parts", {}).values():
        planner = getattr(part, "planner", None)
        if planner is not None:
            timing = dict(planner.timing)
            break
    means = sim.episode_means()
    return {k: means[k].copy() for k in ("nsw", "workforce_cost", "utilization", "downtime")}, wall, timing


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seeds", type=int, default=50, help="seeds 0..n-1")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--policies", default="oracle,oracle-dispatch,solver,heuristic")
    ap.add_argument("--against", default="solver,heuristic")
    a = ap.parse_args()
    from wfbench.analysis.stats import bootstrap_ci, paired_difference

    seeds = list(range(a.first_seed, a.first_seed + a.seeds))
    chunks = [c.tolist() for c in np.array_split(np.array(seeds), a.workers) if len(c)]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"scenario {a.scenario}, seeds {seeds[0]}-{seeds[-1]}, {len(chunks)} worker processes")
    results = {}
    ctx = mp.get_context("spawn")
    with ctx.Pool(len(chunks)) as pool:
        pool.map(run_chunk, [("heuristic", a.scenario, [seeds[0]])] * len(chunks))  # warm the numba cache
        for name in a.policies.split(","):
            start = time.perf_counter()
            out = pool.map(run_chunk, [(name, a.scenario, c) for c in chunks])
            wall = time.perf_counter() - start
            kpis = {k: np.concatenate([o[0][k] for o in out]) for k in out[0][0]}
            results[name] = kpis
            line = f"{name:16s} wall {wall:7.1f} s"
            timing = [o[2] for o in out if o[2]]
            if timing:
                tot = {k: sum(t[k] for t in timing) for k in timing[0]}
                steps = tot["steps"]
                per = tot["act_s"] / steps * 1e3
                share = {k: tot[k] / tot["act_s"] for k in ("shadow_s", "base_s", "workforce_s", "dispatch_s")}
                line += (f" | per decision step (a batch of {len(chunks[0])} envs): {per:.1f} ms"
                         f" = {per / len(chunks[0]):.2f} ms per env-step; shares: "
                         + ", ".join(f"{k[:-2]} {v:.0%}" for k, v in share.items())
                         + f"; roll-forwards: workforce {tot['workforce_rolls']:.0f}, "
                         f"dispatch {tot['dispatch_rolls']:.0f}")
            print(line, flush=True)
    print()
    print("| policy | WC | PUR | AFD | NSW (95% CI) | " + " | ".join(f"NSW - {b} (paired 95% CI), wins"
                                                          for b in a.against.split(",")) + " |")
    print("|---|---|---|---|---|" + "---|" * len(a.against.split(",")))
    for name, k in results.items():
        ci = bootstrap_ci(k["nsw"])
        cells = []
        for base in a.against.split(","):
            if base in results and base != name:
                d = paired_difference(k["nsw"], results[base]["nsw"])
                cells.append(f"{d.format(4)}, {(k['nsw'] > results[base]['nsw']).sum()}/{len(seeds)}")
            else:
                cells.append("-")
        print(f"| {name} | {k['workforce_cost'].mean():.1f} | {k['utilization'].mean():.3f} | "
              f"{k['downtime'].mean():.3f} | {ci.estimate:.4f} [{ci.low:.4f}, {ci.high:.4f}] | " + " | ".join(cells)
              + " |")


if __name__ == "__main__":
    main()
