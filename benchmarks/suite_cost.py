"""What recomputing the 50-seed suite from nothing would cost, by policy and by world, from the committed pieces.

    python benchmarks/suite_cost.py [--no-lookaheads] [--no-members] [--seeds 0-49] [--workers 2] [--top 12]

The estimate is ``wfbench reproduce suite --plan``'s (``wfbench.reproduce.pieces.plan``) for an
empty output folder: each piece's CPU seconds per episode as its committed piece recorded them
(``cpu_s``, the committed runs of ``docs/results``), times the seeds. It plays nothing. The CPU
seconds of a piece are those of the machine and load it was played under (the 2-core VM, mostly
beside other jobs), so the total is an estimate, not a measurement of one run.
``--no-lookaheads`` leaves out the suite's lookaheads (``wfbench.reproduce.suite.LOOKAHEADS``: the
rollouts, the MPC and the network's search); ``--no-members`` the learned methods' training seeds (``NAME#seedK``).
Numbers go to docs/performance.md.
"""

from __future__ import annotations

import argparse
import collections
import tempfile
from pathlib import Path

from wfbench.core.seeds import resolve_seeds
from wfbench.reproduce import pieces, suite
from wfbench.scenarios import get_suite


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-lookaheads", action="store_true", help="leave the lookahead policies out")
    ap.add_argument("--no-members", action="store_true", help="leave the learned methods' training seeds out")
    ap.add_argument("--seeds", default="test", help="the seeds (default: test, 0-49)")
    ap.add_argument("--workers", type=int, default=2, help="workers the wall-time line divides by (default 2)")
    ap.add_argument("--top", type=int, default=12, help="pieces listed, most expensive first (default 12)")
    a = ap.parse_args()

    s = get_suite("suite-v1")
    names = [n for n in suite.default_policies() if not (a.no_lookaheads and n in suite.LOOKAHEADS)]
    names, _ = suite.with_members(names, not a.no_members)
    with tempfile.TemporaryDirectory() as empty:
        todo = pieces.plan([Path(empty)], [*names, "bound"], s.scenarios, resolve_seeds(a.seeds),
                           others=s.scenarios, costs=suite.committed_runs())
    unknown = collections.Counter(m.policy for m in todo if m.cpu_s is None)
    by_policy: collections.Counter[str] = collections.Counter()
    by_world: collections.Counter[str] = collections.Counter()
    for m in todo:
        key = m.policy.split("#")[0] + (" (training seeds)" if "#" in m.policy else "")
        by_policy[key] += m.cpu_s or 0.0
        by_world[m.scenario] += m.cpu_s or 0.0
    total = sum(by_world.values())
    print(f"{len(names)} policies, {len(todo)} pieces: about {total / 3600:.1f} CPU h, "
          f"{total / 3600 / a.workers:.1f} h on {a.workers} workers"
          + (f"; no stored cost for {', '.join(f'{n} ({k} worlds)' for n, k in unknown.items())}" if unknown else ""))
    for title, counts in (("policy", by_policy), ("world", by_world)):
        print(f"\n| {title} | CPU h | share |\n|---|---:|---:|")
        for k, v in counts.most_common():
            if v >= 0.005 * total:
                print(f"| {k} | {v / 3600:.2f} | {100 * v / total:.0f}% |")
        rest = sum(v for v in counts.values() if v < 0.005 * total)
        print(f"| the others | {rest / 3600:.2f} | {100 * rest / total:.0f}% |")
    print(f"\nthe {a.top} largest pieces:")
    for m in sorted(todo, key=lambda m: -(m.cpu_s or 0.0))[:a.top]:
        print(f"  {m.policy} on {m.scenario}: {(m.cpu_s or 0.0) / 60:.0f} CPU min")


if __name__ == "__main__":
    main()
