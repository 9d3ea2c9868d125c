"""Memory of the rollout lookahead against K (issue #43): flat beyond the forks' own rows.

Plays ``rollout-solver-tuned`` (H and R of the 10 ms preset) on one public seed of a scenario
for ``--steps`` steps at each K, under :mod:`tracemalloc` (numpy's arrays are traced), and
prints per K: the bytes the policy holds after its first act (the fork of ``7 K`` rows, its
buffers and the belief), the peak over the later steps above that, and that peak per fork
row. Flat in K means the later steps allocate nothing that grows with K: the forks are made
once per reset and refilled in place.

Run: ``.venv/bin/python benchmarks/lookahead_memory.py --scenario paper-64 --k 1,2,4,8,16``.
Numbers are measurements of this machine, not results.
"""

from __future__ import annotations

import argparse
import tracemalloc

from wfbench.policies.lookahead import Rollout

from wfbench import ScenarioConfig, Simulator, policies
from wfbench.scenarios.resolve import resolve_scenario


def measure(config: ScenarioConfig, K: int, seed: int, steps: int) -> tuple[int, int]:
    sim = Simulator(config, [seed], threads=1)
    obs = sim.reset()
    pol = Rollout(policies.get("solver-tuned"), K=K, H=80, R=20, scenario=config)
    pol.reset([seed])
    tracemalloc.start()
    a = pol.act(obs)  # the first act makes the belief and the fork
    held, _ = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    sim.step(a)
    for _ in range(steps - 1):
        a = pol.act(sim.observe())
        sim.step(a)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return held, peak - held


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--k", default="1,2,4,8,16")
    args = ap.parse_args()
    config = resolve_scenario(args.scenario)
    print(f"{config.name}, seed {args.seed}, {args.steps} steps, H=80, R=20")
    print(f"{'K':>3s} {'held after act 1 (MB)':>22s} {'peak above it (MB)':>19s} {'held per fork row (kB)':>23s}")
    measure(config, 1, args.seed, 2)  # compiled code and caches loaded once, outside what is measured
    for K in (int(x) for x in args.k.split(",")):
        held, extra = measure(config, K, args.seed, args.steps)
        print(f"{K:3d} {held / 1e6:22.2f} {extra / 1e6:19.3f} {held / (7 * K) / 1e3:23.1f}")


if __name__ == "__main__":
    main()
