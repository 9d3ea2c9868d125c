"""What a simulator built from an observation costs (issue #43 goal: at most 1 ms on paper-64).

Plays the heuristic on a scenario, folds every observation into a
:class:`wfbench.core.belief.Belief`, and at a few steps times:

- ``update``: folding one observation in (every step, batch of one);
- ``build 1``: writing one sampled world into a preallocated fork (``sample_into``);
- ``build K``: writing K samples of the environment (K rows);
- ``new fork``: allocating the fork simulator (once per policy reset, not per decision).

Run: ``.venv/bin/python benchmarks/belief_fork.py --scenario paper-64 --k 8``. One core
(``NUMBA_NUM_THREADS`` does not matter: the belief runs in the calling thread). Prints the
median and the 90th percentile of each in microseconds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from wfbench import Simulator, policies
from wfbench.core.belief import Belief
from wfbench.scenarios.resolve import resolve_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--k", type=int, default=8)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    cfg = resolve_scenario(args.scenario)
    sim = Simulator(cfg, [args.seed])
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset([args.seed])
    bel = Belief(cfg)
    bel.reset([args.seed])
    t0 = time.perf_counter()
    fork = bel.simulator(args.k)
    new_fork = time.perf_counter() - t0
    one = np.zeros(1, dtype=np.int64)
    envs, ks = np.zeros(args.k, dtype=np.int64), np.arange(args.k, dtype=np.int64)
    upd, b1, bk = [], [], []
    for t in range(min(args.steps, cfg.horizon - 1)):
        s = time.perf_counter()
        bel.update(obs)
        upd.append(time.perf_counter() - s)
        if t % 20 == 10:
            for _ in range(args.repeat):
                s = time.perf_counter()
                bel.sample_into(fork, one, one)
                b1.append(time.perf_counter() - s)
                s = time.perf_counter()
                bel.sample_into(fork, envs, ks)
                bk.append(time.perf_counter() - s)
        sim.step(pol.act(obs))
        obs = sim.observe()

    def us(x):
        x = np.asarray(x) * 1e6
        return f"median {np.median(x):8.1f} us, p90 {np.percentile(x, 90):8.1f} us ({x.size} timings)"

    print(f"{cfg.name}: M={cfg.max_facilities} N={cfg.max_personnel} window={cfg.window} horizon={cfg.horizon}")
    print(f"update      {us(upd)}")
    print(f"build 1     {us(b1)}")
    print(f"build K={args.k:<3d}{us(bk)}")
    print(f"new fork    {new_fork * 1e3:.1f} ms (once per reset)")


if __name__ == "__main__":
    main()
