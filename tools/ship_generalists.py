"""Ship a learned method trained with several seeds: score each seed, apply the stated rule, copy the files.

    python tools/ship_generalists.py --method ppo-general --runs runs/ppo-general-s0,...,runs/ppo-general-s4 \
        [--seeds public:1010-1019] [--out policies/neural/checkpoints]

Each run's ``best.pt`` (chosen by its own trainer on its selection seeds) is scored on
public seeds it was not selected on (``--seeds``, default 1010-1019), on every world it
was trained on, in the suite's normalized score (:func:`wfbench.train.scoring.score_worlds`).
The shipped pick is the seed with the median score (:func:`wfbench.analysis.aggregate.median_seed`,
the rule fixed before any test seed was run; docs/suite.md, "Learned methods over training
seeds"). Writes each run's file under its name in ``wfbench.policies.registry.seed_runs()``
(``METHOD-seedK.pt``), the shipped pick's (``checkpoint_file(METHOD)``, ``METHOD.pt``) as a byte copy
of the pick (the registry finds the pick by that equality) and ``METHOD-selection.json``:
the scores, the seeds, the rule and the pick. Test seeds are refused.
"""

from __future__ import annotations

import argparse
import json
import shutil
import warnings
from pathlib import Path

import torch
from wfbench.policies.registry import checkpoint_file, member_spec, parse_member, seed_runs

from wfbench import policies
from wfbench.analysis.aggregate import median_seed
from wfbench.core.seeds import SEED_SETS, resolve_seeds
from wfbench.train.scoring import score_worlds
from wfbench.train.worlds import world_set

OUT = Path(__file__).resolve().parent.parent / "policies" / "neural" / "checkpoints"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", required=True, help="the method's name, e.g. ppo-general")
    ap.add_argument("--runs", required=True, help="the run folders, comma-separated, in seed order (seed0 first)")
    ap.add_argument("--seeds", default="1010-1019", help="public seeds to score the seeds' best.pt on")
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args()
    seeds = resolve_seeds(a.seeds)
    if not set(seeds) <= set(SEED_SETS["public"]):
        raise SystemExit(f"--seeds {a.seeds}: the pick is made on public seeds (1000-1049) only")
    if a.method not in seed_runs():
        raise SystemExit(f"--method {a.method}: allowed: a network trained over seeds "
                         f"(wfbench.policies.registry.seed_runs(): {', '.join(seed_runs())})")
    runs = [Path(r) for r in a.runs.split(",")]
    files = seed_runs()[a.method]
    if len(runs) != len(files):
        raise SystemExit(f"--runs: {len(runs)} runs, but {a.method} has {len(files)} training seeds")
    out = Path(a.out)
    scores, detail = {}, {}
    for k, run in enumerate(runs):
        best = run / "best.pt"
        ckpt = torch.load(best, map_location="cpu", weights_only=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = score_worlds(lambda mode, b=best: policies.get(f"ppo:{b}"), world_set(ckpt["scenario"]), seeds)
        member = member_spec(a.method, k)
        scores[member] = res["sample"]
        detail[member] = {"run": str(run), "train_seed": ckpt["train_config"]["seed"], "update": ckpt["update"],
                          "global_step": ckpt["global_step"], "selection": ckpt["best"], "score": res["sample"],
                          "worlds": res["worlds"], "train_wall_s": ckpt.get("train_wall_s")}
        print(f"{member}: {res['sample']:.4f} ({run}, update {ckpt['update']}, {ckpt['global_step']:,} steps)",
              flush=True)
    pick = median_seed(scores)
    out.mkdir(parents=True, exist_ok=True)
    for run, name in zip(runs, files, strict=True):
        shutil.copyfile(run / "best.pt", out / name)
    shutil.copyfile(out / files[parse_member(pick)[1]], out / checkpoint_file(a.method).name)
    record = {"method": a.method, "rule": "the median of the seeds' mean normalized score on the public seeds of "
              "the training scenarios (wfbench.analysis.aggregate.median_seed)", "seeds": seeds, "scores": scores,
              "pick": pick, "members": detail}
    (out / f"{a.method}-selection.json").write_text(json.dumps(record, indent=2) + "\n")
    print(f"pick: {pick} (scores {', '.join(f'{v:.4f}' for v in scores.values())}); wrote {out}")


if __name__ == "__main__":
    main()
