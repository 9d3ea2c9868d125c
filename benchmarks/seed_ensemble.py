"""Does an ensemble of a method's training seeds beat its members? The selection score of each, public seeds only.

An ensemble (:class:`wfbench.policies.neural.ensemble.EnsembleNet`: every member's heads run on
the same features, their logits averaged) spends compute at decision time with no model of
the world. This scores ensembles of ``scalefree-general``'s training seeds, given as digit
strings (``14`` is seeds 1 and 4), beside the shipped network (``net``) and single seeds, on
the trainers' selection score (:func:`wfbench.train.scoring.score_worlds`: the normalized
score on public seeds of the eight training worlds, sampled mode). Public seeds only: these
numbers select, they are not reported results. docs/rl.md, "An ensemble of the training seeds".

    NUMBA_NUM_THREADS=1 python benchmarks/seed_ensemble.py net 01234 1234 124 14 --seeds 1010-1019
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from wfbench import policies
from wfbench.core.seeds import resolve_seeds
from wfbench.train.scoring import score_worlds
from wfbench.train.worlds import world_set

CHECKPOINTS = Path(__file__).resolve().parents[1] / "policies/neural/checkpoints"


def ensemble(seeds: str, method: str = "scalefree-general"):
    """The sampling policy of ``method``'s training seeds named by the digits of ``seeds``, logits averaged."""
    from wfbench.policies.neural.ensemble import EnsembleNet
    from wfbench.policies.neural.policy import NetworkPolicy, build_model, load_checkpoint

    nets = [build_model(load_checkpoint(CHECKPOINTS / f"{method}-seed{int(c)}.pt")) for c in seeds]
    return NetworkPolicy(EnsembleNet(nets), name=f"{method}-ensemble{seeds}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("members", nargs="+", help="'net' (the shipped network) or digit strings of training seeds")
    ap.add_argument("--seeds", default="1010-1019", help="public seeds (default 1010-1019, the shipping rule's)")
    ap.add_argument("--scenarios", default="suite-v1:train")
    args = ap.parse_args()
    seeds = resolve_seeds(args.seeds)
    if any(s < 1000 for s in seeds):
        raise SystemExit(f"--seeds {args.seeds!r} names test seeds; allowed: public seeds (1000-1049)")
    bad = [m for m in args.members if m != "net" and not (m.isdigit() and set(m) <= set("01234"))]
    if bad:
        raise SystemExit(f"members {', '.join(bad)} are not allowed; allowed: net or digit strings of seeds 0-4")
    for m in args.members:
        t = time.process_time()
        make = (lambda mode: policies.get("scalefree-general")) if m == "net" else (lambda mode, m=m: ensemble(m))
        res = score_worlds(make, world_set(args.scenarios), seeds)
        print(json.dumps({"members": m, "score": round(res["sample"], 4), "cpu_s": round(time.process_time() - t, 1),
                          "worlds": {k: round(v, 4) for k, v in res["worlds"].items()}}), flush=True)


if __name__ == "__main__":
    main()
