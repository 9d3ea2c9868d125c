"""Time of the rliable aggregate a board ranking runs, and that its intervals are rliable's own.

A board ranks every entry by the IQM of its normalized scores with stratified bootstrap
intervals (:func:`wfbench.analysis.aggregate.aggregate_suite`, at the board's
``REPS`` replications), so ``wfbench leaderboard show`` and ``wfbench reproduce suite``
spend most of their time there. This times it on random scores shaped like a board
(``--policies`` entries x ``--seeds`` seeds x ``--scenarios`` scenarios), twice:

- ``wfbench``: :func:`~wfbench.analysis.aggregate.aggregate` as the board calls it;
- ``rliable``: the same intervals through rliable's own metric functions
  (``rliable.metrics.aggregate_iqm`` and the rest), the way wfbench computed them before.

It prints both times and whether every point and interval is the same to the bit.

Usage::

    python benchmarks/aggregate_speed.py --policies 10 --seeds 50 --scenarios 1
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def rliable_table(mats: dict[str, np.ndarray], seed: int, reps: int) -> dict[str, np.ndarray]:
    """Points and intervals of IQM, mean and optimality gap through rliable's metric functions alone."""
    from rliable import library as rly
    from rliable import metrics

    from wfbench.analysis.aggregate import _seeded

    def values(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x), metrics.aggregate_optimality_gap(x)])

    out = {}
    for name, m in mats.items():
        with _seeded(seed):
            point, ci = rly.get_interval_estimates({name: m}, values, reps=reps)
        out[name] = np.concatenate([point[name], ci[name][0], ci[name][1]])
    return out


def main() -> None:
    from wfbench.leaderboard.report import REPS

    from wfbench.analysis.aggregate import STATISTICS, aggregate
    from wfbench.harness.budget import machine, machine_line

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policies", type=int, default=10)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--scenarios", type=int, default=1)
    ap.add_argument("--reps", type=int, default=REPS, help=f"bootstrap replications (default the board's, {REPS})")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    mats = {f"p{i}": rng.random((a.seeds, a.scenarios)) for i in range(a.policies)}
    aggregate({"warm": mats["p0"]}, reps=10, profile_reps=10)  # imports rliable and arch once, outside the timing

    t = time.perf_counter()
    ours = aggregate(mats, seed=0, reps=a.reps, profile_reps=10).table
    t_ours = time.perf_counter() - t
    t = time.perf_counter()
    theirs = rliable_table(mats, 0, a.reps)
    t_theirs = time.perf_counter() - t

    cols = [*STATISTICS, *(f"{k}_low" for k in STATISTICS), *(f"{k}_high" for k in STATISTICS)]
    same = all(np.array_equal(ours.set_index("policy").loc[n, cols].to_numpy(dtype=float), v)
               for n, v in theirs.items())
    print(f"{machine_line(machine())}; {a.policies} policies x "
          f"{a.seeds} seeds x {a.scenarios} scenarios, {a.reps} replications")
    print(f"wfbench aggregate (IQM, mean, gap, profiles): {t_ours:.2f} s")
    print(f"rliable's metric functions (IQM, mean, gap):  {t_theirs:.2f} s")
    print(f"every point and interval the same to the bit: {same}")


if __name__ == "__main__":
    main()
