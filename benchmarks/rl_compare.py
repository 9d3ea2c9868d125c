"""The learned policies on the test seeds, paired by seed with the solver and with each other (docs/rl.md).

    python benchmarks/rl_compare.py [--policies hindsight-joint,impala-joint,ppo-joint] [--baseline solver]
                                    [--scenario paper-64] [--seeds test] [--csv per_seed.csv]

Prints the comparison table against the baseline (``wfbench compare``) and the paired NSW
difference, with its bootstrap 95% interval and wins, for every pair of the listed policies.
"""

from __future__ import annotations

import argparse
import itertools

import pandas as pd

from wfbench.analysis.stats import paired_difference
from wfbench.harness.compare import compare, format_comparison


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policies", default="hindsight-joint,impala-joint,ppo-joint")
    ap.add_argument("--baseline", default="solver")
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seeds", default="test")
    ap.add_argument("--csv", default=None, help="also write the per-seed rows of every policy here")
    a = ap.parse_args()
    names = a.policies.split(",")
    df = compare([*names, a.baseline], a.scenario, a.seeds, baseline=a.baseline)
    print(format_comparison(df))
    runs = df.attrs["runs"]
    for x, y in itertools.combinations(names, 2):
        u, v = runs[x]["nsw"].to_numpy(), runs[y]["nsw"].to_numpy()
        d = paired_difference(u, v)
        print(f"{x} - {y}: {d[0]:+.4f} [{d[1]:+.4f}, {d[2]:+.4f}], wins {(u > v).sum()}/{len(u)}")
    if a.csv:
        pd.concat(runs).to_csv(a.csv)


if __name__ == "__main__":
    main()
