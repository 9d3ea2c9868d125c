"""What the rollout lookahead's budget presets cost and score (issue #43), against their base.

Plays ``solver-tuned`` and each ``rollout-solver-tuned`` preset on the same public seeds of
a scenario through ``act`` (one environment per episode, one core), and prints per policy
the mean NSW, the paired difference to the base with its standard error, the decision time
per env-step (p50 of ``act`` and the mean) and how many candidates were rolled out.

Run: ``.venv/bin/python benchmarks/rollout_budget.py --scenario paper-64 --seeds 1000-1003``
(``--presets 1ms,10ms`` for fewer; ``K:H:R`` for other knobs, e.g. ``2:80:80``). Public seeds
only: the presets are chosen on them. ``--steps N`` plays only the first N steps of each
episode, a measurement of cost alone (its NSW is of those steps), for worlds such as ``city``
where whole episodes take long.
Numbers are measurements of this machine at its current load, not results.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from wfbench.policies.lookahead import BUDGETS, Rollout

from wfbench import Simulator, policies
from wfbench.core.seeds import resolve_seeds
from wfbench.scenarios.resolve import resolve_scenario


def play(pol, config, seed, steps=None):
    sim = Simulator(config, [seed], threads=1)
    obs = sim.reset()
    pol.reset([seed])
    times = []
    while not sim.done and (steps is None or len(times) < steps):
        s = time.perf_counter()
        a = pol.act(obs)
        times.append(time.perf_counter() - s)
        sim.step(a)
        obs = sim.observe()
    return float(sim.episode_means()["nsw"][0]), np.asarray(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seeds", default="1000-1003")
    ap.add_argument("--presets", default=",".join(BUDGETS))
    ap.add_argument("--steps", type=int, default=None, help="play only the first STEPS steps (cost alone)")
    args = ap.parse_args()
    config = resolve_scenario(args.scenario)
    seeds = resolve_seeds(args.seeds)
    base = {s: play(policies.get("solver-tuned"), config, s, args.steps) for s in seeds}
    b = np.array([base[s][0] for s in seeds])
    bt = np.concatenate([base[s][1] for s in seeds]) * 1e3
    print(f"{config.name}, seeds {args.seeds}" + (f", the first {args.steps} steps" if args.steps else ""))
    print(f"{'policy':34s} {'NSW':>7s} {'vs base':>16s} {'p50 ms':>8s} {'mean ms':>8s} {'rolls':>8s}")
    print(f"{'solver-tuned':34s} {b.mean():7.4f} {'':>16s} {np.median(bt):8.3f} {bt.mean():8.3f}")
    for preset in args.presets.split(","):
        knobs = dict(zip("KHR", map(int, preset.split(":")), strict=True)) if ":" in preset else {}
        pol = Rollout(policies.get("solver-tuned"), budget=preset if not knobs else "10ms", scenario=config,
                      **knobs)
        runs = [play(pol, config, s, args.steps) for s in seeds]
        r = np.array([x[0] for x in runs])
        t = np.concatenate([x[1] for x in runs]) * 1e3
        d = r - b
        se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else float("nan")
        name = f"rollout-solver-tuned@{preset} {pol.settings()}"
        print(f"{name:34s} {r.mean():7.4f} {d.mean():+8.4f} ± {se:6.4f} {np.median(t):8.3f} {t.mean():8.3f} "
              f"{pol.timing['rolls']:8.0f}")


if __name__ == "__main__":
    main()
