"""Compute a suite's normalization constants and write them beside the suite (wfbench/scenarios/<suite>.json).

For each scenario: ``random_ref``, the mean NSW of the ``random`` policy, and ``bound_ref``,
the mean proven upper bound (wfbench.core.bound), over the test seeds 0-49; with the
scenario's hash, so that a later change of its definition is refused by
``wfbench.scenarios.normalize``. The file records the seeds, the wfbench version and the
suite's hash (when all its presets exist). Scenarios already in the file with the same
hash are kept unless ``--force``; scenarios whose preset does not exist yet are skipped
and named.

    .venv/bin/python tools/suite_references.py                     # every scenario of suite-v1
    .venv/bin/python tools/suite_references.py --scenarios small-v1 city-v1

tests/scenarios/test_suite.py recomputes the constants of a cheap scenario and checks they match.
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import wfbench
from wfbench.core.seeds import describe
from wfbench.harness.backends import Execution
from wfbench.harness.suite import compute_reference
from wfbench.scenarios import DATA, REFERENCE_SEEDS, get_suite, suite_scenarios


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--suite", default="suite-v1")
    p.add_argument("--scenarios", nargs="*", default=None, help="scenario ids (default: all of the suite)")
    p.add_argument("--backend", default="serial", help="evaluation backend of the random policy's runs")
    p.add_argument("--force", action="store_true", help="recompute scenarios already in the file")
    args = p.parse_args()
    path = DATA / f"{args.suite}.json"
    data = json.loads(path.read_text()) if path.exists() else {"scenarios": {}}
    scenarios = suite_scenarios(args.suite, available_only=True)
    wanted = set(args.scenarios) if args.scenarios else None
    seeds = list(REFERENCE_SEEDS)
    for sc in scenarios:
        if wanted is not None and sc.id not in wanted and sc.preset not in wanted:
            continue
        old = data["scenarios"].get(sc.id)
        if old and old["hash"] == sc.hash and not args.force:
            print(f"{sc.id}: kept ({old['random_ref']:.6f}, {old['bound_ref']:.6f})")
            continue
        t0 = time.perf_counter()
        data["scenarios"][sc.id] = compute_reference(sc, seeds, execution=Execution(backend=args.backend))
        r = data["scenarios"][sc.id]
        print(f"{sc.id}: random {r['random_ref']:.6f}, bound {r['bound_ref']:.6f} "
              f"({time.perf_counter() - t0:.1f} s)", flush=True)
    try:
        suite_hash = get_suite(args.suite).hash
    except ValueError as exc:  # a preset of the suite is not there yet
        print(f"note: {exc}")
        suite_hash = None
    order = [s.id for s in scenarios]
    data = {
        "suite": args.suite,
        "suite_hash": suite_hash,
        "seeds": seeds,
        "seeds_described": describe(seeds),
        "wfbench_version": wfbench.__version__,
        "python": platform.python_version(),
        "made_by": "tools/suite_references.py",
        "random_ref": "mean NSW of the 'random' policy over the seeds",
        "bound_ref": "mean of wfbench.core.bound.score_upper_bound over the seeds",
        "scenarios": {k: data["scenarios"][k] for k in sorted(data["scenarios"], key=lambda k: (
            order.index(k) if k in order else len(order), k))},
    }
    path.write_text(json.dumps(data, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
