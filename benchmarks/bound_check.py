"""Check the proven score upper bound (issue #12) on many seeds and report it per scenario.

For each scenario: the mean bound over the seeds (with its min and max), its margin below
the trivial bound 1, and for each policy its mean score, its mean share of the bound
(score / bound per seed) and the number of seeds where it scores above the bound (must
be 0). The oracles (``oracle``, ``oracle-dispatch``, when registered) read the trace and
are slower; they run on the first ``--oracle-seeds`` seeds.

    .venv/bin/python benchmarks/bound_check.py --seeds 200 --oracle-seeds 50
    .venv/bin/python benchmarks/bound_check.py --scenarios small paper-64 --json bound.json

The numbers quoted in docs/hindsight.md ("The upper bound") come from the first command.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import wfbench
from wfbench import policies
from wfbench.core.bound import score_upper_bound
from wfbench.core.config import ScenarioConfig

SCENARIOS = ["small", "paper-64", "nonstationary", "table2-g32-f25-s10"]
POLICIES = ["random", "heuristic", "heuristic-stochastic", "solver", "random-dispatch", "fixed-workforce"]
ORACLES = ["oracle-planner", "oracle-dispatch"]  # the planners; the oracle (best in hindsight) is >= them


def play(name: str, config: ScenarioConfig, seeds: list[int]) -> np.ndarray:
    """Episode scores of a policy (the runner hands a trace-reading oracle its scenario)."""
    return wfbench.evaluate(name, config, seeds=seeds)["nsw"].to_numpy()


def check(scenario: str, n_seeds: int, n_oracle: int) -> dict:
    """The bound of ``scenario`` on seeds ``0..n_seeds-1`` against every policy; one report row."""
    config = ScenarioConfig.preset(scenario)
    seeds = list(range(n_seeds))
    t0 = time.perf_counter()
    bound = score_upper_bound(config, seeds)
    row = {"scenario": scenario, "seeds": n_seeds, "bound_s": round(time.perf_counter() - t0, 2),
           "bound_mean": float(bound.mean()), "bound_min": float(bound.min()), "bound_max": float(bound.max()),
           "margin_below_1": float(1.0 - bound.mean()), "policies": {}}
    names = [(p, seeds) for p in POLICIES] + [(p, seeds[:n_oracle]) for p in ORACLES if p in policies.names()]
    for name, run_seeds in names:
        score = play(name, config, run_seeds)
        b = bound[: len(run_seeds)]
        row["policies"][name] = {"seeds": len(run_seeds), "score": float(score.mean()),
                                 "share": float((score / b).mean()), "bound_on_these_seeds": float(b.mean()),
                                 "violations": int((score > b).sum())}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=SCENARIOS)
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--oracle-seeds", type=int, default=50)
    ap.add_argument("--json", default=None, help="also write the rows to this file")
    args = ap.parse_args()
    rows = []
    for scenario in args.scenarios:
        row = check(scenario, args.seeds, min(args.oracle_seeds, args.seeds))
        rows.append(row)
        print(f"\n{scenario}: bound {row['bound_mean']:.4f} (min {row['bound_min']:.4f}, max {row['bound_max']:.4f}) "
              f"over {row['seeds']} seeds in {row['bound_s']} s; trivial bound 1, margin {row['margin_below_1']:.4f}")
        print(f"  {'policy':22s} {'seeds':>5s} {'score':>7s} {'bound':>7s} {'share':>6s} {'over':>4s}")
        for name, r in row["policies"].items():
            print(f"  {name:22s} {r['seeds']:5d} {r['score']:7.4f} {r['bound_on_these_seeds']:7.4f} "
                  f"{r['share']:6.3f} {r['violations']:4d}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)
    bad = [(r["scenario"], n) for r in rows for n, p in r["policies"].items() if p["violations"]]
    if bad:
        raise SystemExit(f"the bound was exceeded: {bad}")


if __name__ == "__main__":
    main()
