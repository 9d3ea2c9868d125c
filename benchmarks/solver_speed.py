"""Per-step time of the dispatch and positioning methods, and env-steps/s with them in the loop.

    python benchmarks/solver_speed.py [--quick] [--json out.json]

1. Dispatch: one decision on an observation with n open requests and n free people
   at random positions on a 64x64 grid (n = 25, 50, 200; sizes of the issue), for the
   greedy heuristic (``nearest``), the compiled optimal assignment (``assignment``),
   and the solver-package methods through Python (``assignment-scipy``, ``-milp``,
   ``-lp`` on HiGHS, ``-lp-osqp``). Median of repeated calls.
2. Positioning at the paper's size (50 facility slots, 25 active, 25 people): the
   spatial heuristic and the p-median policy forced to re-solve every step, and the
   p-median solve alone by each method.
3. Whole episodes on paper-64 with 50 seeds batched: env-steps/s of the heuristic and
   of each solver composite; the Python-path dispatch methods on fewer seeds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.builtin import BuiltinDecision
from wfbench.solvers import facility_location

from wfbench import policies
from wfbench.core.observe import make_obs
from wfbench.harness.bench import machine
from wfbench.scenarios.resolve import resolve_scenario


def random_obs(M: int, N: int, n_active: int, n_req: int, n_people: int, seed: int = 0, grid: int = 64):
    """Facilities and people at random cells; the first ``n_req`` facilities request service."""
    rng = np.random.default_rng(seed)
    facilities = [(rng.integers(grid), rng.integers(grid), f < n_req) for f in range(n_active)]
    people = []
    for _ in range(n_people):
        x, y = rng.integers(grid), rng.integers(grid)
        people.append((x, y, x, y, rng.integers(3)))
    obs = make_obs(M, N, facilities, people)
    obs["facilities"][0, :n_active, 6] = rng.random(n_active) * 0.5  # some downtime history
    return obs


def time_calls(fn, repeats: int, budget_s: float = 5.0) -> float:
    fn()  # warm-up: compilation, cvxpy build
    times = []
    start = time.perf_counter()
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if time.perf_counter() - start > budget_s:
            break
    return statistics.median(times)


def dispatch_per_step(sizes, repeats):
    rows = []
    for n in sizes:
        obs = random_obs(n, n, n, n, n, seed=n)
        for name in ("nearest", "assignment", "assignment-scipy", "assignment-milp", "assignment-lp",
                     "assignment-lp-osqp"):
            if name == "assignment-lp-osqp" and n > 50:
                rows.append({"bench": "dispatch", "size": f"{n}x{n}", "method": name, "ms": None,
                             "note": "skipped: OSQP needs minutes at this size (see docs/solvers.md)"})
                continue
            pol = policies.DECISIONS["dispatch"][name]()
            pol.reset([0])
            n_calls = repeats if "lp" not in name else max(3, repeats // 10)
            s = time_calls(lambda pol=pol, obs=obs: pol.act(obs), n_calls)
            rows.append({"bench": "dispatch", "size": f"{n}x{n}", "method": name, "ms": s * 1e3})
            print(f"dispatch {n}x{n} {name:<20s} {s * 1e3:9.3f} ms", flush=True)
    return rows


def lp_first_vs_resolve():
    """cvxpy compiles a problem once per shape; later solves only swap parameter values."""
    from wfbench.solvers import assignment

    rows = []
    rng = np.random.default_rng(3)
    for lp_solver in ("HIGHS", "OSQP"):
        for n in (10, 25, 50):
            assignment._LP_CACHE.clear()
            t0 = time.perf_counter()
            first = assignment.solve(rng.random((n, n)), method="lp", lp_solver=lp_solver)
            t_first = time.perf_counter() - t0
            again = []
            for _ in range(5):
                t0 = time.perf_counter()
                r = assignment.solve(rng.random((n, n)), method="lp", lp_solver=lp_solver)
                again.append(time.perf_counter() - t0)
                assert not r.detail["rebuilt"]
            assert first.detail["rebuilt"]
            t_again = statistics.median(again)
            rows.append({"bench": "LP first solve vs re-solve", "size": f"{n}x{n}", "method": f"lp-{lp_solver}",
                         "first_ms": t_first * 1e3, "resolve_ms": t_again * 1e3})
            print(f"LP {lp_solver:<5s} {n}x{n}: first solve {t_first * 1e3:8.1f} ms, re-solve {t_again * 1e3:8.1f} ms",
                  flush=True)
    return rows


def positioning_per_step(repeats):
    rows = []
    obs = random_obs(50, 50, 25, 5, 25, seed=7)
    for name, pol in (("spatial", policies.DECISIONS["positioning"]["spatial"]()),
                      ("facility-location (solve every step)",
                       BuiltinDecision("positioning", K.P_FACILITY, "facility-location", refresh=1.0))):
        pol.reset([0])
        t = [0]

        def step(pol=pol, t=t):
            t[0] += 1
            obs["t"][0] = t[0]
            pol.act(obs)

        s = time_calls(step, repeats)
        rows.append({"bench": "positioning", "size": "25 sites, 25 people", "method": name, "ms": s * 1e3})
        print(f"positioning {name:<40s} {s * 1e3:9.3f} ms", flush=True)
    rng = np.random.default_rng(0)
    pts = rng.integers(0, 64, size=(25, 2))
    D = np.abs(pts[:, None, :] - pts[None, :, :]).sum(-1).astype(float)
    w = rng.random(25)
    for method in facility_location.METHODS:
        s = time_calls(lambda m=method: facility_location.solve_p_median(D, 13, method=m, weights=w),
                       repeats if method == "local-search" else 20)
        rows.append({"bench": "p-median solve", "size": "25 sites, p=13", "method": method, "ms": s * 1e3})
        print(f"p-median 25 sites p=13 {method:<14s} {s * 1e3:9.3f} ms", flush=True)
    return rows


def episodes(n_seeds: int, slow_seeds: int, slow_steps: int):
    from wfbench.core.config import ScenarioConfig
    from wfbench.core.simulator import Simulator
    from wfbench.harness.runner import run_batch

    rows = []
    paper = ScenarioConfig.preset("paper-64")
    for name in ("heuristic", "solver-dispatch", "solver-workforce", "solver-positioning", "solver"):
        run_batch(name, paper, [0, 1])
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            r = run_batch(name, paper, list(range(n_seeds)))
            best = min(best, time.perf_counter() - t0)
        rate = float(r.steps.sum()) / best
        rows.append({"bench": "episodes", "size": f"paper-64 x {n_seeds} seeds", "method": name,
                     "env_steps_per_s": rate})
        print(f"episodes paper-64 x{n_seeds} {name:<20s} {rate:12,.0f} env-steps/s", flush=True)
    for name in ("nearest", "assignment-scipy", "assignment-milp", "assignment-lp"):
        pol = policies.get(f"{name}+threshold+spatial")
        sim = Simulator(resolve_scenario("paper-64"), list(range(slow_seeds)), keep_series=False)
        obs = sim.reset()
        pol.reset(sim.seeds)
        t0 = time.perf_counter()
        while sim.t < slow_steps:
            sim.step(pol.act(obs))
            obs = sim.observe()
        rate = slow_seeds * slow_steps / (time.perf_counter() - t0)
        rows.append({"bench": "episodes (Python loop)", "method": name, "env_steps_per_s": rate,
                     "size": f"paper-64 x {slow_seeds} seeds, {slow_steps} steps"})
        print(f"python loop paper-64 x{slow_seeds} {name:<20s} {rate:12,.0f} env-steps/s", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    print(machine())
    rows = dispatch_per_step((25, 50) if args.quick else (25, 50, 200), 50 if args.quick else 200)
    rows += lp_first_vs_resolve()
    rows += positioning_per_step(50 if args.quick else 500)
    rows += episodes(50, 5 if args.quick else 50, 50 if args.quick else 200)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": machine(), "rows": rows}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
