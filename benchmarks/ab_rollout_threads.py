"""Interleaved A/B of the compiled rollout by thread count between checkouts of wfbench.

    python benchmarks/ab_rollout_threads.py CHECKOUT_A CHECKOUT_B [--pairs 3] [--batch 1024] [--threads 1,2]

Each measurement is a fresh process that imports wfbench from one checkout (put first
on ``PYTHONPATH``; one virtual environment serves both) and times
``wfbench.policies.episode.play_episodes`` of the heuristic on ``paper-64`` (traces built before the
clock, best of 3 whole batches) on each thread count. The processes alternate
A, B, A, B, ... so that the drift of a shared machine hits both. Each checkout gets its
own numba cache (``NUMBA_CACHE_DIR`` and ``WFBENCH_CACHE_DIR`` under ``--cache``); the
first process of each compiles, untimed.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, time
from wfbench.policies import get
from wfbench.policies.episode import play_episodes
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario
B, counts = int(sys.argv[1]), [int(t) for t in sys.argv[2].split(",")]
seeds = list(range(B))
warm = Simulator(resolve_scenario("paper-64"), [0], keep_series=False)
rollout(warm, *get("heuristic").compiled_plan([0], warm.M, warm.N), threads=1)  # loads the kernel
out = {}
for threads in counts:
    sim = Simulator(resolve_scenario("paper-64"), seeds, keep_series=False)
    best = float("inf")
    for _ in range(3):
        plan = get("heuristic").compiled_plan(seeds, sim.M, sim.N)
        t0 = time.perf_counter()
        play_episodes(sim, *plan, threads=threads)
        best = min(best, time.perf_counter() - t0)
    out[threads] = B * sim.config.horizon / best
print("RESULT " + json.dumps(out))
"""


def measure(checkout: str, cache: Path, B: int, threads: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(checkout), NUMBA_CACHE_DIR=str(cache),
               WFBENCH_CACHE_DIR=str(cache / "wfbench"))
    out = subprocess.run([sys.executable, "-c", CHILD, str(B), threads], env=env, capture_output=True, text=True,
                         cwd=cache)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-4000:])
    line = next(line for line in out.stdout.splitlines() if line.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkouts", nargs=2)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--cache", default="/tmp/wfbench-ab-cache")
    args = ap.parse_args()
    caches = []
    for i, checkout in enumerate(args.checkouts):
        cache = Path(args.cache) / f"{i}-{Path(checkout).resolve().name}"
        cache.mkdir(parents=True, exist_ok=True)
        caches.append(cache)
        measure(checkout, cache, 1, "1")  # compiles into this checkout's cache, untimed
    results = {c: [] for c in args.checkouts}
    for p in range(args.pairs):
        for checkout, cache in zip(args.checkouts, caches, strict=True):
            r = measure(checkout, cache, args.batch, args.threads)
            results[checkout].append(r)
            print(f"[{p + 1}] {checkout}: " + ", ".join(f"{t} thread(s) {v:,.0f}" for t, v in r.items()), flush=True)
    for checkout, runs in results.items():
        for t in runs[0]:
            values = [r[t] for r in runs]
            print(f"{checkout}, B={args.batch}, {t} thread(s): {min(values):,.0f} - {max(values):,.0f} env-steps/s")


if __name__ == "__main__":
    main()
