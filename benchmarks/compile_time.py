"""Cold compile time of the compiled core, by entry point and by function.

    python benchmarks/compile_time.py [--src CHECKOUT ...] [--target simulator|rollout|both] [--repeat N]
    python benchmarks/compile_time.py [--src CHECKOUT ...] --policy NAME [--repeat N]

Each measurement runs in a fresh child process with an empty numba cache (a new
temporary ``WFBENCH_CACHE_DIR`` and ``NUMBA_CACHE_DIR``), so everything it uses is
compiled from scratch:

- ``simulator``: ``Simulator(resolve_scenario("paper-64"), [0])``: reset, ``step_observe``, ``step``,
  ``observe`` (what an environment compiles);
- ``rollout``: ``wfbench.policies.episode.play_episodes`` of the heuristic on ``paper-64``, one seed,
  one thread (the compiled whole-episode rollout with the built-in kernels; what
  ``wfbench evaluate`` compiles);
- ``--policy NAME``: ``wfbench.evaluate(NAME, "paper-64", [0])``, what a user's first
  ``wfbench evaluate --policy NAME`` compiles (any registered family, the lookaheads included).

With several ``--src`` checkouts the children alternate between them (A, B, A, B, ...),
so a slow spell of a shared machine hits both. Each child reports its wall and CPU time and,
through numba's ``numba:compile`` events, the CPU time spent compiling each function:
inclusive (its callees compiled on the way included) and exclusive (its own typing,
lowering and LLVM optimization). CPU time, because on a shared machine the wall time
of a compilation mostly measures the other processes. ``--top`` prints the slowest functions by exclusive time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

CHILD = r"""
import json, os, sys, time
t_start = time.perf_counter()
if os.environ.get("COMPILE_TIME_SRC"):  # wfbench and the folders it maps, all from that checkout
    sys.path.insert(0, os.environ["COMPILE_TIME_BENCHMARKS"])
    from identity_check import from_checkout
    wrong = from_checkout(os.environ["COMPILE_TIME_SRC"])
    if wrong:
        sys.exit(f"compile_time: {wrong}")
from numba.core import event

stack, times = [], {}

class Timer(event.Listener):
    def on_start(self, ev):
        stack.append([time.process_time(), 0.0])

    def on_end(self, ev):
        t0, children = stack.pop()
        d = ev.data["dispatcher"]
        name = f"{d.py_func.__module__}.{d.py_func.__qualname__}"
        total = time.process_time() - t0
        inc, exc = times.get(name, (0.0, 0.0))
        times[name] = (inc + total, exc + total - children)
        if stack:
            stack[-1][1] += total

event.register("numba:compile", Timer())
target = sys.argv[1]
import numpy as np
from wfbench.scenarios.resolve import resolve_scenario
if target in ("simulator", "both"):
    from wfbench.core.simulator import Simulator
    sim = Simulator(resolve_scenario("paper-64"), [0])
    sim.reset()
    M, N = sim.M, sim.N
    a = {"dispatch": np.full((1, M), N, dtype=np.int64), "workforce": np.zeros(1, dtype=np.int64),
         "positioning": np.zeros((1, 2, M))}
    sim.step_observe(a)
    sim.step(a)
    sim.observe()
if target in ("rollout", "both"):
    from wfbench.policies import get
    from wfbench.policies.episode import play_episodes
    from wfbench.core.simulator import Simulator
    sim = Simulator(resolve_scenario("paper-64"), [0], keep_series=False)
    play_episodes(sim, *get("heuristic").compiled_plan([0], sim.M, sim.N), threads=1)
if target.startswith("policy:"):  # what a user's first evaluate of this policy compiles
    import wfbench
    wfbench.evaluate(target[len("policy:"):], "paper-64", [0])
wall = time.perf_counter() - t_start
print("RESULT " + json.dumps({"wall_s": wall, "cpu_s": time.process_time(), "functions": times}))
"""


def measure(src: str | None, target: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="wfbench-cold-") as cache:
        env = dict(os.environ, WFBENCH_CACHE_DIR=cache, NUMBA_CACHE_DIR=cache)
        if src:  # a PYTHONPATH alone would import policies/ from the editable install's checkout
            env["COMPILE_TIME_SRC"] = os.path.abspath(src)
            env["COMPILE_TIME_BENCHMARKS"] = os.path.dirname(os.path.abspath(__file__))
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", CHILD, target], env=env, capture_output=True, text=True,
                             cwd=tempfile.gettempdir())
        elapsed = time.perf_counter() - t0
        if out.returncode != 0:
            raise RuntimeError(out.stderr[-4000:])
        line = next(line for line in out.stdout.splitlines() if line.startswith("RESULT "))
        result = json.loads(line[len("RESULT "):])
        result["process_s"] = elapsed
        result["stderr"] = out.stderr
        return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", action="append", help="checkout to import wfbench from (repeat to alternate)")
    ap.add_argument("--target", default="both", choices=("simulator", "rollout", "both"))
    ap.add_argument("--policy", help="measure the first wfbench.evaluate of this registered policy instead of --target")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--json", help="write every measurement to this file")
    args = ap.parse_args()
    if args.policy:
        args.target = f"policy:{args.policy}"
    sources = args.src or [None]
    runs = []
    for r in range(args.repeat):
        for src in sources:
            res = measure(src, args.target)
            fn = res["functions"]
            compile_s = sum(exc for _, exc in fn.values())
            print(f"[{r + 1}] {src or 'installed'} {args.target}: wall {res['process_s']:.1f} s, CPU "
                  f"{res['cpu_s']:.1f} s, compiling {compile_s:.1f} s CPU in {len(fn)} functions", flush=True)
            for line in res["stderr"].splitlines():
                print(f"    stderr: {line}")
            for name, (inc, exc) in sorted(fn.items(), key=lambda kv: -kv[1][1])[: args.top]:
                print(f"    {exc:7.1f} s own {inc:7.1f} s incl (CPU)  {name}")
            runs.append({"src": src, "target": args.target, **res})
    if args.json:
        with open(args.json, "w") as f:
            json.dump(runs, f, indent=2)


if __name__ == "__main__":
    main()
