"""Today's MPC presets, bit for bit: episode NSW of mpc-ma, mpc-rates and mpc-ma-calibrated (issue #53).

Plays each on paper-64, public seeds 1000-1002 (one batch, the runner in process) and writes the
per-seed NSW as exact hex floats to a JSON file. Run it at two commits and compare the files: a
change that adds an MPC option (``backlog=True``) must leave them equal.

    NUMBA_NUM_THREADS=1 python benchmarks/mpc_identity.py /tmp/before.json   # at the older commit
    NUMBA_NUM_THREADS=1 python benchmarks/mpc_identity.py /tmp/after.json --compare /tmp/before.json
"""

from __future__ import annotations

import argparse
import json

from wfbench import policies
from wfbench.harness.runner import run_batch
from wfbench.scenarios.resolve import resolve_scenario

NAMES = ("mpc-ma", "mpc-rates", "mpc-ma-calibrated")
SEEDS = (1000, 1001, 1002)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="the JSON file to write: name -> per-seed NSW as hex floats")
    ap.add_argument("--compare", default=None, help="a file written before: say whether every number is equal")
    a = ap.parse_args()
    pols = {n: policies.get(n) for n in NAMES}  # built first: the modules measured are the ones imported now
    config = resolve_scenario("paper-64")
    out = {}
    for n in NAMES:
        nsw = run_batch(pols[n], config, list(SEEDS)).means["nsw"]
        out[n] = [float(v).hex() for v in nsw]
        print(n, [round(float(v), 4) for v in nsw], flush=True)
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)
    if a.compare:
        with open(a.compare) as f:
            before = json.load(f)
        same = before == out
        print("bit-identical" if same else f"DIFFERENT: before {before}, after {out}")
        raise SystemExit(0 if same else 1)


if __name__ == "__main__":
    main()
