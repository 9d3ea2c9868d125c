"""The trainers' selection score of any policy: its normalized score on the public seeds of the training split.

What ``wfbench train --scenarios suite-v1:train`` picks ``best.pt`` by
(:func:`wfbench.train.scoring.score_worlds`), for policies given by name (modes with
``@``), so a teacher, its student and the shipped networks are compared on one scale. Public
seeds only: these numbers select, they are not reported results.

    python benchmarks/public_scores.py scalefree-general scalefree-general@greedy rollout-solver-tuned
"""

from __future__ import annotations

import argparse
import json
import time

from wfbench import policies
from wfbench.core.seeds import resolve_seeds
from wfbench.train.scoring import score_worlds
from wfbench.train.worlds import world_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("policies", nargs="+", help="policy names, e.g. scalefree-general@greedy-workforce")
    ap.add_argument("--scenarios", default="suite-v1:train")
    ap.add_argument("--seeds", default="public:5", help="public seeds (test seeds are refused by the seed sets)")
    args = ap.parse_args()
    seeds = resolve_seeds(args.seeds)
    if any(s < 1000 for s in seeds):
        raise SystemExit(f"--seeds {args.seeds!r} names test seeds; allowed: public seeds (1000-1049)")
    for name in args.policies:
        t = time.process_time()
        res = score_worlds(lambda mode, name=name: policies.get(name), world_set(args.scenarios), seeds)
        print(json.dumps({"policy": name, "score": res["sample"], "cpu_s": round(time.process_time() - t, 1),
                          "worlds": res["worlds"]}), flush=True)


if __name__ == "__main__":
    main()
