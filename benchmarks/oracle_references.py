"""The references against the bound: a reference's score per seed, each candidate's, where each came from (issue #53).

For one scenario and some seeds, prints per seed and on the mean: the proven bound, the
first reference (``oracle``, v1), and a replaying reference (default ``oracle-v2``) with
every candidate's score (``oracle.scores``: NaN where the candidate was stopped early, below
the best already found), the choice, where each candidate's totals came from
(``oracle.sources``) and the seconds each took. ``--alone`` plays candidates alone first, never
stopped early, so that their scores are all known; their episodes are stored and the
reference replays them. ``--without`` leaves candidates out of the
replaying reference (say so when quoting it: the result is then a lower bound of the whole
reference's score, which is the best of more candidates). ``--json`` writes it all.
docs/hindsight.md quotes it ("How far the references are from the bound").

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/oracle_references.py --scenario paper-64-v1 --seeds 1000-1004
    python benchmarks/oracle_references.py --scenario large-v1 --seeds 1000-1004 \\
        --without rollout-solver-tuned-100ms,rollout-solver-sparse-tuned-100ms
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
from wfbench.policies.oracle.best import BestInHindsight

from wfbench import Simulator, policies
from wfbench.core.bound import score_upper_bound
from wfbench.core.seeds import resolve_seeds
from wfbench.scenarios import get_suite


def play(policy, config, seeds) -> np.ndarray:
    """Mean NSW per seed, played as the runner plays a built-in that reads the trace."""
    sim = Simulator(config, seeds, keep_series=False, threads=1)
    obs = sim.reset()
    policy.attach(config)
    policy.reset(sim.seeds)
    while not sim.done:
        sim.step(policy.act(obs))
        obs = sim.observe()
    return sim.episode_means()["nsw"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64-v1", help="a suite-v1 scenario id")
    ap.add_argument("--seeds", default="1000-1004", help="a seed spec (wfbench.core.seeds)")
    ap.add_argument("--reference", default="oracle-v2", help="the replaying reference to measure")
    ap.add_argument("--without", default="", help="candidates to leave out of it, comma-separated")
    ap.add_argument("--first", action=argparse.BooleanOptionalAction, default=True, help="also play oracle (v1)")
    ap.add_argument("--alone", default="", help="candidates to play alone first (never stopped early; their episodes "
                    "are stored, so the reference replays them), comma-separated")
    ap.add_argument("--json", default="", help="write the numbers to this file")
    args = ap.parse_args()
    config = get_suite("suite-v1").scenario(args.scenario).config
    seeds = list(resolve_seeds(args.seeds))
    print(f"{platform.node()}: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; {args.scenario}, seeds "
          f"{args.seeds}", flush=True)
    out: dict = {"scenario": args.scenario, "seeds": seeds}
    t0 = time.perf_counter()
    out["bound"] = score_upper_bound(config, seeds).tolist()
    print(f"bound {np.mean(out['bound']):.4f} {np.round(out['bound'], 4).tolist()} ({time.perf_counter() - t0:.0f} s)",
          flush=True)
    if args.first:
        t0 = time.perf_counter()
        first = policies.get("oracle")
        out["oracle"] = play(first, config, seeds).tolist()
        out["oracle_choice"] = first.choice
        print(f"oracle {np.mean(out['oracle']):.4f} {np.round(out['oracle'], 4).tolist()} {first.choice} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    out["alone"] = {}
    for name in [n for n in args.alone.split(",") if n]:
        t0 = time.perf_counter()
        alone = BestInHindsight([name], policies.get, name=name, replay=True)
        out["alone"][name] = play(alone, config, seeds).tolist()
        print(f"{name} {np.mean(out['alone'][name]):.4f} {np.round(out['alone'][name], 4).tolist()} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    without = {n for n in args.without.split(",") if n}
    ref = policies.get(args.reference)
    ref = BestInHindsight([n for n in ref.candidates if n not in without], policies.get, name=args.reference,
                          replay=ref.replay)
    t0 = time.perf_counter()
    out[args.reference] = play(ref, config, seeds).tolist()
    wall = time.perf_counter() - t0
    out["choice"] = ref.choice
    out["candidates"] = {n: ref.scores[:, k].tolist() for k, n in enumerate(ref.candidates)}
    out["sources"], out["timing"], out["without"] = ref.sources, ref.timing, sorted(without)
    for k, n in enumerate(ref.candidates):
        col = ref.scores[:, k]
        mean = f"{np.mean(col):.4f}" if not np.isnan(col).any() else "stopped"
        print(f"  {n:36s} {mean:>8s} {np.round(col, 4).tolist()} {ref.sources.get(n)} {ref.timing[n]:.0f} s")
    gap = np.mean(out["bound"]) - np.mean(out[args.reference])
    name = args.reference + (" without " + ",".join(sorted(without)) if without else "")
    print(f"{name}: {np.mean(out[args.reference]):.4f} {np.round(out[args.reference], 4).tolist()} {ref.choice} "
          f"({wall:.0f} s); the bound {gap:.4f} above", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
