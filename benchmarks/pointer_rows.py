"""Why the networks before the scale-free one cannot compute only the dispatch rows they read (issue #35).

On ``city`` their dispatch head builds a (B, M, N + 1) block every step: the pointer
product ``q @ k.T`` of every facility with every person, minus a multiple of the
facility-person distance, with the no-op column appended. Their sampler reads only the
rows of the facilities with a real choice (about 3% on ``city``), so computing only those
rows would save most of the block, but only if the rows kept their bits: a network's
published numbers are its sampled episodes, and one changed bit in a logit can change a
pick.

This script measures, at the shapes of a shipped network on a scenario's slot counts:

- the cost of each part of the block for a batch of environments (one torch thread);
- whether the pointer product of a subset of rows equals the same rows of the full
  product, bit for bit, for several subset sizes (per environment, ``q[rows] @ k.T``);
- the same for the elementwise parts (distance and subtraction), which are exact by
  construction (one rounding per element, whatever the shape).

The answer on the project's VM (docs/performance.md): the elementwise parts keep their
bits, and they are most of the block's cost; the product of a subset does not keep them
for a single row (BLAS takes a matrix-vector path there), and which shapes do is BLAS's
choice, not ours. So an exact "only the rows read" keeps the full product and computes
only the read rows of the distance, the subtraction and the no-op column.

Usage::

    python benchmarks/pointer_rows.py --network ppo-general --scenario city --batch 25
"""

from __future__ import annotations

import argparse
import math
import time

import torch
from wfbench.policies.neural.model import manhattan
from wfbench.policies.registry import get

from wfbench.harness.budget import machine, machine_line
from wfbench.scenarios.resolve import resolve_scenario


def pointer_width(network: str) -> int:
    """The width of the pointer's queries and keys in a shipped network (its ``ptr_q`` layer)."""
    policy = get(network)
    model = getattr(policy, "model", None)
    if model is None:
        raise SystemExit(f"{network!r} has no single network (a composite of several); name one that does, "
                         "such as ppo-general or ppo-joint")
    for module in model.modules():
        if hasattr(module, "ptr_q"):
            return int(module.ptr_q.out_features)
    raise SystemExit(f"{network!r} has no pointer dispatch head (ptr_q); name a network that dispatches")


def ms(fn, repeat: int) -> float:
    """Median milliseconds of ``fn()`` over ``repeat`` calls after one warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    times.sort()
    return times[len(times) // 2] * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--network", default="ppo-general")
    ap.add_argument("--scenario", default="city")
    ap.add_argument("--batch", type=int, default=25, help="environments per call (the suite's chunk on 2 workers)")
    ap.add_argument("--rows", default="1,2,3,8,32,128,512", help="subset sizes to compare with the full product")
    ap.add_argument("--trials", type=int, default=20, help="random subsets per size and environment")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    torch.set_num_threads(1)
    config = resolve_scenario(args.scenario)
    B, M, N, d = args.batch, config.max_facilities, config.max_personnel, pointer_width(args.network)
    gen = torch.Generator().manual_seed(0)
    q, k = torch.randn(B, M, d, generator=gen), torch.randn(B, N, d, generator=gen)
    fac_xy, per_xy = torch.rand(B, M, 2, generator=gen) * 9, torch.rand(B, N, 2, generator=gen) * 9
    noop = torch.randn(B, M, 1, generator=gen)

    product = q @ k.transpose(-1, -2) / math.sqrt(d)
    dist = manhattan(fac_xy, per_xy)
    logits = product - 0.75 * dist
    print(f"{args.network} (pointer width {d}) on {config.name}: B={B}, M={M}, N={N}, one torch thread")
    print(f"  pointer product      {ms(lambda: q @ k.transpose(-1, -2) / math.sqrt(d), args.repeat):8.1f} ms")
    print(f"  distance             {ms(lambda: manhattan(fac_xy, per_xy), args.repeat):8.1f} ms")
    print(f"  minus the distance   {ms(lambda: product - 0.75 * dist, args.repeat):8.1f} ms")
    print(f"  no-op column (cat)   {ms(lambda: torch.cat([logits, noop], -1), args.repeat):8.1f} ms")

    print("  subset rows vs the full block, bit for bit (per environment, random rows):")
    for r in (int(x) for x in args.rows.split(",")):
        same_product = same_elementwise = 0
        for t in range(args.trials):
            b = t % B
            rows = torch.randperm(M, generator=gen)[:r]
            part = q[b, rows] @ k[b].T / math.sqrt(d)
            same_product += torch.equal(part, product[b, rows])
            sub = manhattan(fac_xy[b, rows], per_xy[b])
            same_elementwise += torch.equal(product[b, rows] - 0.75 * sub, logits[b, rows])
        print(f"    {r:4d} rows: product equal in {same_product}/{args.trials}, "
              f"distance and subtraction equal in {same_elementwise}/{args.trials}")
    print(f"torch {torch.__version__}; {machine_line(machine())}")


if __name__ == "__main__":
    main()
