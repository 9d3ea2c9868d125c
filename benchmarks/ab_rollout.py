"""Interleaved A/B of the compiled rollout kernel between two checkouts of wfbench.

    python benchmarks/ab_rollout.py /path/to/checkout_a
    python benchmarks/ab_rollout.py /path/to/checkout_b    # alternate a, b, a, b ...

Times ``wfbench.policies.episode.play_parallel`` on an already built batch (the traces are
not in the clock), heuristic policy, ``paper-64``, best of 3 (of 20 at B = 1). The
checkout given is put first on ``sys.path``, so one virtual environment serves both.
Run the two checkouts alternately: this machine's speed drifts from minute to minute
(docs/performance.md), so only interleaved runs compare.
"""

import sys
import time

if len(sys.argv) != 2:
    sys.exit("usage: python benchmarks/ab_rollout.py CHECKOUT")
sys.path.insert(0, sys.argv[1])

import numba  # noqa: E402
import numpy as np  # noqa: E402
from wfbench.policies import get  # noqa: E402
from wfbench.policies.episode import play_parallel  # noqa: E402

from wfbench.core.simulator import Simulator  # noqa: E402
from wfbench.harness.runner import run_batch  # noqa: E402
from wfbench.scenarios.resolve import resolve_scenario

config = resolve_scenario("paper-64")
run_batch("heuristic", config, [0], threads=1)  # loads (or compiles) the kernels
rates = []
for B, threads in ((1, 1), (1024, 1), (1024, 2)):
    sim = Simulator(config, list(range(B)), keep_series=False)
    dispatch = np.full((B, sim.M), sim.N, dtype=np.int64)
    workforce = np.zeros(B, dtype=np.int64)
    positioning = np.zeros((B, 2, sim.M))
    numba.set_num_threads(threads)
    best = float("inf")
    for _ in range(3 if B > 1 else 20):
        codes, hp, pstate = get("heuristic").compiled_plan(list(range(B)), sim.M, sim.N)
        t0 = time.perf_counter()
        play_parallel(sim.state, sim.trace, sim.params, sim.obs_buffers, pstate, codes, hp, dispatch, workforce,
                         positioning)
        best = min(best, time.perf_counter() - t0)
    rates.append(f"B={B}, {threads} thread(s): {B * config.horizon / best:,.0f} env-steps/s")
print(sys.argv[1], "|", " | ".join(rates))
