"""What the lookahead presets for ``city`` cost and score (issue #53, item 1), against solver-sparse and the network.

Plays each policy on the same public seeds of a scenario, one environment per episode, one core
(``NUMBA_NUM_THREADS=1``, one torch thread), and prints per policy the mean NSW, the paired
difference to the first policy with its standard error, and the cost: CPU milliseconds per
env-step, the CPU seconds of the whole episodes (act and step) over their env-steps, and of
``act`` alone. ``sparse-twin:NAME`` plays the sparse twin of a registered composite (the
rollout's base, no lookahead); ``variant:BUDGET:DECIDE:FUTURES`` (``base`` or ``spatial``) the
sparse rollout of solver-tuned with the presets' other choices (``variant:10ms:period:spatial``
is ``rollout-solver-sparse-tuned``).

Run: ``python benchmarks/lookahead_city.py --scenario city --seeds 1000-1002`` (``--steps N``
plays only the first N steps of each episode: its NSW is then of those steps). Public seeds
only. Numbers are measurements of this machine at its current load, not results.
"""

from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"  # before numba is imported: one core

import argparse
import json
import platform
import time

import numpy as np

from wfbench import Simulator, policies
from wfbench.core.seeds import PUBLIC, resolve_seeds
from wfbench.scenarios.resolve import resolve_scenario

DEFAULT = ("solver-sparse", "scalefree-general", "sparse-twin:solver-tuned", "rollout-solver-sparse-tuned-1ms",
           "rollout-solver-sparse-tuned")


def make(spec: str):
    if spec.startswith("variant:"):  # variant:BUDGET:DECIDE:FUTURES, FUTURES base or spatial: the presets' choices
        from wfbench.policies.lookahead.rollout import Rollout, sparse_twin, spatial_twin

        _, budget, decide, futures = spec.split(":")
        base = policies.get("solver-tuned")
        return Rollout(base, budget=budget, sparse=True, decide=decide,
                       futures=spatial_twin(sparse_twin(base)) if futures == "spatial" else None, name=spec)
    if spec.startswith("sparse-twin:"):
        from wfbench.policies.lookahead.rollout import sparse_twin

        return sparse_twin(policies.get(spec.partition(":")[2]))
    return policies.get(spec)


def play(spec: str, config, seed: int, steps: int | None) -> dict[str, float]:
    pol = make(spec)
    if hasattr(pol, "set_world"):
        pol.set_world(config)  # what the evaluator hands a lookahead (wfbench.harness.runner.public_world)
    sim = Simulator(config, [seed], threads=1)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    obs = sim.reset()
    pol.reset([seed])
    n, act_cpu = 0, 0.0
    while not sim.done and (steps is None or n < steps):
        a0 = time.process_time()
        a = pol.act(obs)
        act_cpu += time.process_time() - a0
        sim.step(a)
        obs = sim.observe()
        n += 1
    cpu = time.process_time() - cpu0
    timing = getattr(pol, "timing", {}) or {}
    return {"nsw": float(sim.episode_means()["nsw"][0]), "steps": n, "cpu_s": cpu, "act_cpu_s": act_cpu,
            "wall_s": time.perf_counter() - wall0, "decisions": float(timing.get("decisions", 0.0))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="city")
    ap.add_argument("--seeds", default="1000-1002", help="public seeds, e.g. 1000-1002 or 1000,1001 ('1000' "
                    "alone is a count)")
    ap.add_argument("--policies", default=",".join(DEFAULT), help="comma-separated; the first is the reference")
    ap.add_argument("--steps", type=int, default=None, help="play only the first STEPS steps of each episode")
    ap.add_argument("--json", default=None, help="also write the per-seed rows here")
    args = ap.parse_args()
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass
    config = resolve_scenario(args.scenario)
    seeds = resolve_seeds(args.seeds)
    if not set(seeds) <= set(PUBLIC):  # "1000" alone is a count (seeds 0-999): the test seeds are for results only
        ap.error(f"--seeds {args.seeds} names seeds outside public 1000-1049; give a range such as 1000-1002")
    names = args.policies.split(",")
    print(f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores, load {os.getloadavg()}, "
          f"python {platform.python_version()}; {config.name}, seeds {args.seeds}"
          + (f", the first {args.steps} steps" if args.steps else ", whole episodes"), flush=True)
    print(f"{'policy':36s} {'NSW':>7s} {'vs first':>17s} {'ms/step':>9s} {'act ms':>9s} {'decisions':>9s}", flush=True)
    rows, ref = {}, None
    for name in names:
        runs = [play(name, config, s, args.steps) for s in seeds]
        rows[name] = runs
        nsw = np.array([r["nsw"] for r in runs])
        steps = sum(r["steps"] for r in runs)
        ms = 1e3 * sum(r["cpu_s"] for r in runs) / steps
        act_ms = 1e3 * sum(r["act_cpu_s"] for r in runs) / steps
        if ref is None:
            ref, vs = nsw, ""
        else:
            d = nsw - ref
            se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else float("nan")
            vs = f"{d.mean():+8.4f} ± {se:6.4f}"
        decisions = sum(r["decisions"] for r in runs)
        print(f"{name:36s} {nsw.mean():7.4f} {vs:>17s} {ms:9.2f} {act_ms:9.2f} {decisions:9.0f}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"scenario": config.name, "seeds": seeds, "steps": args.steps, "machine": platform.platform(),
                       "cores": os.cpu_count(), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
