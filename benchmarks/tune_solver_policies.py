"""Choose the solver policies' free parameters on development seeds, never on the reported ones.

    python benchmarks/tune_solver_policies.py [--seeds 50] [--seed-start 1000]

Each parameter is swept with the other two decisions left to the heuristics (the
one-at-a-time composites of docs/solvers.md), on seeds 1000..1049 of paper-64; the
tables in docs/solvers.md use seeds 0..49. Prints NSW and the paired difference to the
heuristic for each value.
"""

from __future__ import annotations

import argparse
import sys

from policies import Composite
from policies import kernels as K
from policies.builtin import BuiltinDecision
from wfbench.evaluation import evaluate
from wfbench.stats import paired_difference

SWEEPS = {
    ("dispatch", K.D_ASSIGN, "revisit_cost"): (0.0, 1.0, 2.0, 5.0, 10.0, 20.0),
    ("workforce", K.W_STAFFING, "beta"): (0.0, 0.25, 0.5, 0.75, 1.0),
    ("workforce", K.W_STAFFING, "hysteresis"): (0.0, 1.0, 2.0, 4.0),
    ("positioning", K.P_FACILITY, "demand_floor"): (0.0, 0.1, 0.5, 2.0),
    ("positioning", K.P_FACILITY, "refresh"): (1.0, 10.0, 30.0),
}
HEURISTIC = {"dispatch": "nearest", "workforce": "threshold", "positioning": "spatial"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--seed-start", type=int, default=1000)
    ap.add_argument("--scenario", default="paper-64")
    args = ap.parse_args(argv)
    seeds = list(range(args.seed_start, args.seed_start + args.seeds))
    base = evaluate("heuristic", args.scenario, seeds)["nsw"].to_numpy()
    print(f"heuristic NSW {base.mean():.4f} on {args.scenario} seeds {seeds[0]}..{seeds[-1]}")
    for (decision, code, field), values in SWEEPS.items():
        for v in values:
            parts = dict(HEURISTIC)
            parts[decision] = BuiltinDecision(decision, code, f"{field}={v}", **{field: v})
            df = evaluate(Composite(**parts), args.scenario, seeds)
            d = paired_difference(df["nsw"].to_numpy(), base)
            print(f"{decision:<12s} {field:<13s} {v:6g}: NSW {df['nsw'].mean():.4f}  vs heuristic {d.format(4)}  "
                  f"WC {df['workforce_cost'].mean():5.2f} PUR {df['utilization'].mean():.3f} "
                  f"AFD {df['downtime'].mean():.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
