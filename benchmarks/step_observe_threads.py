"""Env-steps/s of ``Simulator.step_observe`` by thread count, with precomputed random actions.

    python benchmarks/step_observe_threads.py [--scenario paper-64] [--batch 1024] [--threads 1,2] [--rounds 5]
                                              [--prange] [--no-workforce]

One process, one simulator per variant (same seeds, same actions), the variants
alternated round by round so that a slow spell of a shared machine hits each of them.
Each round steps every simulator ``--steps`` times (32 precomputed batches of random
actions, cycled: random dispatch, random workforce actions, uniform positioning
weights; ``--no-workforce``: the workforce no-op instead), resetting at the horizon.
At the end it checks that every variant holds the same state and observation, byte for
byte, and prints best, median and worst round.

``--prange`` adds, for each thread count above one, the same step as a numba ``prange``
loop (``parallel=True``, compiled here, not cached): the design wfbench did not take
(docs/performance.md, "Threads"). It prints the CPU seconds that compiling it took.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from numba import njit, prange

from wfbench.core.dynamics import step_env
from wfbench.core.entrypoints import bind
from wfbench.core.observe import observe_env
from wfbench.core.simulator import Simulator
from wfbench.core.state import METRICS
from wfbench.scenarios.resolve import resolve_scenario


@njit(_nrt=False)
def _one_env(b, S, Tr, P, O, dispatch, workforce, positioning, with_masks):
    step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])
    observe_env(b, S, P, O, with_masks, True)


@njit(parallel=True)
def _prange_step_observe(S, Tr, P, O, dispatch, workforce, positioning, with_masks):
    for b in prange(S.t.shape[0]):
        _one_env(b, S, Tr, P, O, dispatch, workforce, positioning, with_masks)


class PrangeSimulator(Simulator):
    """``step_observe`` through the ``prange`` kernel on ``threads`` numba threads."""

    def step_observe(self, actions, with_masks=True):
        d, w, p = self._checked(actions)
        args = (self.state, self.trace, self.params, self.obs_buffers, d, w, p, bool(with_masks))
        previous = numba.get_num_threads()
        numba.set_num_threads(self.threads)
        try:
            self.call(_prange_step_observe, *args)
        finally:
            numba.set_num_threads(previous)
        return self.state.last[:, METRICS.index("nsw")].copy(), self._obs_dict()


def random_actions(sim: Simulator, count: int, seed: int = 0, workforce: bool = True) -> list[dict]:
    """``count`` batches of random actions; ``workforce=False``: the workforce no-op throughout."""
    rng = np.random.default_rng(seed)
    B, M, N = sim.B, sim.M, sim.N
    return [{"dispatch": rng.integers(0, N + 1, size=(B, M), dtype=np.int64),
             "workforce": rng.integers(0, 7 if workforce else 1, size=B, dtype=np.int64),
             "positioning": rng.random((B, 2, M))} for _ in range(count)]


def run(sim: Simulator, actions: list[dict], steps: int, start: int) -> int:
    """Step ``steps`` times from action ``start`` on; resets at the horizon. Returns the next action index."""
    i = start
    for _ in range(steps):
        if sim.done:
            sim.reset()
        sim.step_observe(actions[i % len(actions)])
        i += 1
    return i


def same_bits(a: Simulator, b: Simulator) -> bool:
    pairs = list(zip(a.state, b.state, strict=True)) + list(zip(a.obs_buffers, b.obs_buffers, strict=True))
    return all(x.tobytes() == y.tobytes() for x, y in pairs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--threads", default=f"1,{numba.config.NUMBA_NUM_THREADS}")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--prange", action="store_true", help="also time a numba prange kernel")
    ap.add_argument("--no-workforce", action="store_true", help="workforce no-op actions (no hires, no let-gos)")
    args = ap.parse_args()
    counts = sorted({int(t) for t in args.threads.split(",")})
    seeds = list(range(args.batch))
    config = resolve_scenario(args.scenario)
    variants = {f"{t} thread{'s' if t > 1 else ''}": Simulator(config, seeds, keep_series=False, threads=t)
                for t in counts}
    if args.prange:
        for t in counts:
            if t > 1:
                variants[f"{t} threads, prange"] = PrangeSimulator(config, seeds, keep_series=False, threads=t)
    actions = random_actions(next(iter(variants.values())), 32, workforce=not args.no_workforce)
    for sim in variants.values():
        sim.reset()
        if isinstance(sim, PrangeSimulator) and not _prange_step_observe.overloads:
            t0 = time.process_time()
            a = sim._checked(actions[0])
            bind(_prange_step_observe, sim.state, sim.trace, sim.params, sim.obs_buffers, *a, True)
            print(f"compiling the prange kernel: {time.process_time() - t0:.1f} s CPU", flush=True)
        run(sim, actions, 3, 0)  # compiles or loads the kernels
    rates: dict[str, list[float]] = {name: [] for name in variants}
    position = dict.fromkeys(variants, 3)
    print(f"{args.scenario}, B={args.batch}, {args.steps} steps per round, {args.rounds} rounds, "
          f"{'no-op' if args.no_workforce else 'random'} workforce actions")
    for r in range(args.rounds):
        for name, sim in variants.items():
            t0 = time.perf_counter()
            position[name] = run(sim, actions, args.steps, position[name])
            rates[name].append(args.batch * args.steps / (time.perf_counter() - t0))
        print(f"  round {r + 1}: " + ", ".join(f"{n} {v[-1]:,.0f}" for n, v in rates.items()), flush=True)
    sims = list(variants.values())
    assert all(same_bits(sims[0], s) for s in sims[1:]), "the variants disagree"
    print("  same state and observations in every variant")
    print(f"  {'env-steps/s':<24s} {'best':>12s} {'median':>10s} {'worst':>10s}")
    for name, v in rates.items():
        print(f"  {name:<24s} {max(v):>12,.0f} {float(np.median(v)):>10,.0f} {min(v):>10,.0f}")


if __name__ == "__main__":
    main()
