"""The cost of a network's decision against the size of the world (issue #32): time per act and its largest tensor.

For each scenario (``small`` to ``city``) and each network, one environment (B = 1), one
torch thread: the policy's ``act`` on the observations of an episode the network plays
itself, timed call by call after ``--warmup`` calls (the simulator's step is not counted).
It prints the median and 99th percentile milliseconds per env-step, and the largest single
allocation torch made during ``--profiled`` act calls (``torch.profiler``, CPU memory): the
dense (M, N + 1) dispatch block of the networks before the scale-free one grows with
facilities x people; the scale-free network's largest block should not. Usage::

    python benchmarks/network_decision.py --networks ppo-general,scalefree-general --steps 200 --json out.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import machine, machine_line
from wfbench.scenarios.resolve import resolve_scenario

SCENARIOS = ["small", "paper-64", "large", "city"]


def largest_allocation(policy, obs: dict, calls: int) -> int:
    """The largest CPU memory (bytes) any one torch operator allocated in ``calls`` act calls."""
    with torch.profiler.profile(activities=[torch.profiler.ProfilerActivity.CPU], profile_memory=True) as prof:
        for _ in range(calls):
            policy.act(obs)
    return max((e.cpu_memory_usage for e in prof.events() if e.cpu_memory_usage > 0), default=0)


def measure(network: str, scenario: str, steps: int, warmup: int, profiled: int, seed: int = 1000) -> dict:
    pol = policies.get(network)
    sim = Simulator(resolve_scenario(scenario), [seed], keep_series=False, threads=1)
    obs = sim.reset()
    pol.reset([seed])
    times = []
    for t in range(warmup + steps):
        t0 = time.perf_counter()
        act = pol.act(obs)
        if t >= warmup:
            times.append(time.perf_counter() - t0)
        obs = sim.step_observe(act)[1]
        if sim.done:  # a short episode (small: 200 steps) starts again
            obs = sim.reset()
            pol.reset([seed])
    peak = largest_allocation(pol, obs, profiled)
    ms = np.array(times) * 1e3
    c = sim.config
    return {"network": network, "scenario": scenario, "slots": [c.max_facilities, c.max_personnel],
            "steps": steps, "ms_p50": float(np.median(ms)), "ms_p99": float(np.percentile(ms, 99)),
            "largest_alloc_bytes": int(peak)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--networks", default="ppo-general,scalefree-general")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--profiled", type=int, default=5)
    ap.add_argument("--json", default="")
    a = ap.parse_args()
    torch.set_num_threads(1)
    rows = []
    for net in a.networks.split(","):
        for sc in a.scenarios.split(","):
            r = measure(net, sc, a.steps, a.warmup, a.profiled)
            rows.append(r)
            print(f"{net:20s} {sc:10s} slots {r['slots'][0]:5d} x {r['slots'][1]:5d}  "
                  f"{r['ms_p50']:8.2f} ms p50  {r['ms_p99']:8.2f} ms p99  largest tensor "
                  f"{r['largest_alloc_bytes'] / 1024:9.1f} KiB", flush=True)
    print(machine_line(machine()))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"machine": machine(), "torch_threads": 1, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
