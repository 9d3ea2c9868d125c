"""Cost of ``Simulator.reset(indices, seeds)`` against the batch size B (docs/performance.md).

For each B, times (median of ``--repeats`` calls, after a warm-up call):

- ``full``: ``sim.reset()``, every environment, same seeds;
- ``k=..``: ``sim.reset(indices=k random environments)``, same seeds;
- ``k=.. new``: the same onto k new seeds (their traces regenerated and written in);
- ``repad``: one ``reset(indices=[0], seeds=[s])`` whose trace needs wider arrival
  arrays than the batch has (a copy of the batch's arrival rows and a rebinding of
  the compiled entry points), measured on a fresh simulator each time.

The simulators run without the per-step series (``keep_series=False``, what a trainer
uses); ``--series`` keeps it (a reset then also zeroes the row's horizon x 9 floats).

Usage::

    python benchmarks/partial_reset.py --scenario paper-64 --batch 16,256,1024 --k 1,8,64
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from wfbench.scenarios.resolve import resolve_scenario


def median_time(fn, repeats: int) -> float:
    fn()  # warm-up (binds the compiled entry point)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--batch", default="16,256,1024", help="comma-separated batch sizes B")
    ap.add_argument("--k", default="1,8,64", help="comma-separated numbers of environments to reset")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--series", action="store_true", help="keep the per-step series")
    args = ap.parse_args()

    import wfbench
    from wfbench import Simulator

    config = resolve_scenario(args.scenario)
    print(f"{config.name}: M={config.max_facilities} N={config.max_personnel} horizon={config.horizon}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"keep_series={args.series}; median of {args.repeats}")
    ks = [int(k) for k in args.k.split(",")]
    rng = np.random.default_rng(0)
    batches = [int(b) for b in args.batch.split(",")]
    widths = {s: wfbench.trace(config, s).arr_t.shape[1] for s in range(2000, 2000 + 2 * max(batches))}
    print(f"{'B':>6} {'full':>10} " + " ".join(f"{f'k={k}':>10} {f'k={k} new':>10}" for k in ks)
          + f" {'repad':>10}   (ms)")
    for B in batches:
        sim = Simulator(config, list(range(B)), keep_series=args.series, threads=1)
        sim.reset()
        row = [median_time(sim.reset, args.repeats)]
        for k in ks:
            if k > B:
                row += [float("nan")] * 2
                continue
            row.append(median_time(lambda k=k, sim=sim, B=B: sim.reset(indices=rng.choice(B, k, replace=False)),
                                   args.repeats))
            row.append(median_time(lambda k=k, sim=sim, B=B: sim.reset(indices=rng.choice(B, k, replace=False),
                                                                       seeds=rng.integers(10**6, 2 * 10**6, k)),
                                   args.repeats))
        # a seed wider than the batch: fresh simulators on the B narrowest seeds, each widened once by the widest
        base = sorted(widths, key=widths.get)[:B]
        wide = max(widths, key=widths.get)
        A = Simulator(config, base, keep_series=args.series).trace.arr_t.shape[1]
        times = []
        for _ in range(max(3, args.repeats // 5)):
            fresh = Simulator(config, base, keep_series=args.series, threads=1)
            fresh.reset()
            start = time.perf_counter()
            fresh.reset(indices=[0], seeds=[wide])
            times.append(time.perf_counter() - start)
            assert fresh.trace.arr_t.shape[1] > A, "the wide seed did not widen the batch"
        row.append(float(np.median(times)))
        print(f"{B:>6} " + " ".join(f"{1000 * x:>10.3f}" for x in row))


if __name__ == "__main__":
    main()
