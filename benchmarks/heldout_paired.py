"""A policy on the held-out scenarios' test seeds, paired by seed with a committed piece of another policy.

For a policy that is not (yet) a row of the committed suite, e.g. a training run's checkpoint:
it is played here (one core), and each scenario's mean NSW is set beside the reference
policy's committed pieces (those the frontier reads: ``wfbench.reproduce.frontier.DEFAULT_REUSE``)
on the same seeds, with the paired difference and its standard error, and the CPU ms per
env-step the frontier uses. Reported numbers only: nothing here is tuned or selected on.

    NUMBA_NUM_THREADS=1 python benchmarks/heldout_paired.py distill:docs/results/distill-general/seed0/best.pt \\
        --against scalefree-general --seeds 0-19

With ``--committed`` the policy's own committed pieces are read instead (nothing is played), and
``--kpis`` adds each KPI's mean for both, to see where a difference comes from:

    python benchmarks/heldout_paired.py search-scalefree-general --committed --seeds 0-49 \\
        --kpis hires,releases,headcount,workforce_cost,utilization,downtime
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.reproduce.frontier import DEFAULT_REUSE

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = tuple(ROOT / run for run in DEFAULT_REUSE)  # the committed runs the frontier reads, in its order
HELDOUT = ("large-v1", "table2-g128-f50-s25-v1", "table2-g32-f100-s25-v1", "slow-64-v1", "churn-64-v1",
           "novice-64-v1", "real-nyc-v1")


def committed(policy: str, scenario: str, seeds=None, folders=FOLDERS) -> pd.DataFrame:
    """The first piece of ``policy`` on ``scenario`` in ``folders`` that holds every one of ``seeds``."""
    from wfbench.scenarios.pieces import first_piece

    df = first_piece(folders, policy, scenario, seeds)
    if df is not None:
        return df
    raise SystemExit(f"heldout_paired: no committed piece of {policy!r} on {scenario} with seeds "
                     f"{min(seeds) if seeds else ''}-{max(seeds) if seeds else ''} in "
                     + ", ".join(str((f / "cache").relative_to(ROOT)) for f in folders))


def main() -> None:
    import wfbench
    from wfbench.core.seeds import resolve_seeds

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("policy", help="a policy spec (registry name, ALGO:PATH, ...)")
    ap.add_argument("--against", default="scalefree-general", help="the committed policy to pair with")
    ap.add_argument("--seeds", default="0-19", help="test seeds (default 0-19)")
    ap.add_argument("--scenarios", default=",".join(HELDOUT), help="scenario ids (default: the held-out ones but "
                    "city; a training world's numbers are reported the same way)")
    ap.add_argument("--committed", action="store_true", help="read the policy's committed pieces, play nothing")
    ap.add_argument("--folders", default=None, help="comma-separated suite runs whose cache/ to read, in order "
                    "(default: docs/results/suite-v1-50, docs/results/frontier-v1); docs/results/reference-v2 first "
                    "pairs a network with its play in the same ten-seed batches as the campaign's pieces")
    ap.add_argument("--kpis", default="", help="comma-separated result columns whose means to add, policy / against "
                    "(e.g. hires,releases,headcount,workforce_cost,utilization,downtime)")
    args = ap.parse_args()
    seeds = resolve_seeds(args.seeds)
    folders = FOLDERS if args.folders is None else tuple(ROOT / f for f in args.folders.split(","))
    kpis = [k for k in args.kpis.split(",") if k]
    print("| scenario | NSW, policy | NSW, " + args.against + " | paired difference (± s.e.) | CPU ms / env-step |"
          + "".join(f" {k} |" for k in kpis))
    print("|---|---|---|---|---|" + "---|" * len(kpis))
    for sc in args.scenarios.split(","):
        if args.committed:
            df = committed(args.policy, sc, seeds, folders).loc[seeds].reset_index()
        else:
            with warnings.catch_warnings():  # zero-shot on a held-out world is the point
                warnings.simplefilter("ignore")
                df = wfbench.evaluate(args.policy, sc, seeds=seeds, execution=wfbench.Execution(threads=1))
        ref = committed(args.against, sc, seeds, folders).loc[seeds]
        d = df["nsw"].to_numpy() - ref["nsw"].to_numpy()
        ms = 1e3 * df["cpu_s"].sum() / df["episode_length"].sum()
        extra = "".join(f" {df[k].mean():.3g} / {ref[k].mean():.3g} |" for k in kpis)
        print(f"| {sc} | {df['nsw'].mean():.4f} | {ref['nsw'].mean():.4f} | {d.mean():+.4f} ± "
              f"{d.std(ddof=1) / np.sqrt(len(d)):.4f} | {ms:.2f} |{extra}", flush=True)


if __name__ == "__main__":
    main()
