"""In-process A/B: the compiled rollout with the full observation against the lean one.

    python benchmarks/ab_observation.py [B] [repeats]

Both episode loops are compiled in this process (not cached; ~2 minutes) and run
alternately, heuristic policy, ``paper-64``, one thread, so the machine's drift hits
both alike (docs/performance.md). Prints the best rate of each and checks that the two
give the same per-step series.
"""

import sys
import time

import numpy as np
from numba import njit
from wfbench.policies import get
from wfbench.policies.kernels import act_codes

from wfbench.core.dynamics import reset_env, step_env
from wfbench.core.observe import observe_env
from wfbench.core.simulator import Simulator
from wfbench.scenarios.resolve import resolve_scenario


@njit(_nrt=False)
def _episodes(S, Tr, P, O, PS, codes, hp, dispatch, workforce, positioning, full):
    for b in range(S.t.shape[0]):
        reset_env(b, S, Tr, P)
        while S.t[b] < P.horizon:
            observe_env(b, S, P, O, False, full)
            act_codes(codes[0], codes[1], codes[2], b, O, PS, hp, dispatch, workforce, positioning, S.t[b], True)
            step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])


def main() -> None:
    B = int(sys.argv[1]) if len(sys.argv) > 1 else 256
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 6
    config = resolve_scenario("paper-64")
    sim = Simulator(config, list(range(B)), keep_series=True)
    dispatch = np.full((B, sim.M), sim.N, dtype=np.int64)
    workforce = np.zeros(B, dtype=np.int64)
    positioning = np.zeros((B, 2, sim.M))
    best = {True: float("inf"), False: float("inf")}
    series = {}
    for rep in range(repeats + 1):  # the first round compiles
        for full in (True, False):
            codes, hp, pstate = get("heuristic").compiled_plan(list(range(B)), sim.M, sim.N)
            t0 = time.perf_counter()
            _episodes(sim.state, sim.trace, sim.params, sim.obs_buffers, pstate, codes, hp, dispatch, workforce,
                      positioning, full)
            if rep > 0:
                best[full] = min(best[full], time.perf_counter() - t0)
            series[full] = sim.state.series.copy()
    for full in (True, False):
        print(f"{'full' if full else 'lean'} observation: {B * config.horizon / best[full]:,.0f} env-steps/s")
    print("same series:", np.array_equal(series[True], series[False]))


if __name__ == "__main__":
    main()
