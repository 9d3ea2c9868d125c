"""Interleaved A/B of the PettingZoo environment step between two checkouts of wfbench.

    python benchmarks/ab_env.py /path/to/checkout_a
    python benchmarks/ab_env.py /path/to/checkout_b    # alternate a, b, a, b ...

Times ``parallel_env("paper-64").step()`` with pre-sampled random actions, exactly as
``wfbench bench`` does (``wfbench.harness.bench._pettingzoo_rate``), best of 3 x 3,000 steps.
The checkout given is put first on ``sys.path``, so one virtual environment serves
both. Run the checkouts alternately: this machine's speed drifts from minute to minute
(docs/performance.md), so only interleaved runs compare.
"""

import sys

if len(sys.argv) != 2:
    sys.exit("usage: python benchmarks/ab_env.py CHECKOUT")
sys.path.insert(0, sys.argv[1])

import wfbench  # noqa: E402
from wfbench.harness.bench import _pettingzoo_rate  # noqa: E402

if not wfbench.__file__.startswith(sys.argv[1]):
    sys.exit(f"wfbench was imported from {wfbench.__file__}, not from {sys.argv[1]}")
config = wfbench.scenario("paper-64")
_pettingzoo_rate(config, 200)  # loads (or compiles) the kernels
print(f"{sys.argv[1]}: PettingZoo step, random actions, {max(_pettingzoo_rate(config, 3000) for _ in range(3)):,.0f} "
      "steps/s")
