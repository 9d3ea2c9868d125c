"""Learning curves over training seeds: the median and the band (min-max) of the runs' public scores, as a PNG.

    python benchmarks/plot_seed_curves.py RUN_DIR [RUN_DIR ...] --out docs/img/ppo-general-seeds.png \
        [--reference ppo-joint,heuristic,solver-tuned] [--title "..."] [--offset 0]

Reads each run's ``latest.pt`` history (the scores on its public selection seeds that the
trainer logged: the mean normalized score over the worlds for a run across worlds, the
mean NSW otherwise). Left: the score by environment steps, the median over the runs as a
line and the band from the lowest to the highest run; each ``--reference`` policy scored
on the same seeds and worlds as a dashed line. Right: the median over the runs per world.
``--offset`` draws the steps after that many (a run started with ``--init``).
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import matplotlib

from wfbench import policies

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from wfbench.train.scoring import score_worlds  # noqa: E402
from wfbench.train.worlds import world_set  # noqa: E402


def history(run: Path) -> list[dict]:
    ckpt = torch.load(run / "latest.pt", map_location="cpu", weights_only=False)
    return [h for h in ckpt["history"] if h.get("sample") is not None], ckpt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--out", required=True)
    ap.add_argument("--reference", default="")
    ap.add_argument("--title", default="")
    ap.add_argument("--offset", type=int, default=0)
    a = ap.parse_args()
    hist, ckpt = zip(*(history(Path(r)) for r in a.runs), strict=True)
    steps = sorted(set.intersection(*({h["global_step"] for h in hs} for hs in hist)))
    by = [{h["global_step"]: h for h in hs} for hs in hist]
    score = np.array([[b[s]["sample"] for s in steps] for b in by])  # (runs, steps)
    x = np.array(steps) + a.offset
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5))
    left.fill_between(x, score.min(0), score.max(0), alpha=0.25, label=f"min-max over {len(a.runs)} seeds")
    left.plot(x, np.median(score, 0), lw=2, label="median over seeds")
    seeds = hist[0][0]["seeds"]
    scenario = ckpt[0]["scenario"]
    refs = {}
    for name in filter(None, a.reference.split(",")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            refs[name] = score_worlds(lambda mode, n=name: policies.get(n), world_set(scenario), seeds)
        left.axhline(refs[name]["sample"], ls="--", lw=1, color=f"C{len(refs) + 1}", label=name)
    unit = "mean normalized score over the worlds" if hist[0][0].get("scale") == "normalized" else "mean NSW"
    left.set(xlabel="environment steps", ylabel=f"{unit}, public seeds {seeds[0]}-{seeds[-1]}")
    left.legend(fontsize=8)
    worlds = list(hist[0][0].get("worlds", {}))
    for i, w in enumerate(worlds):
        per = np.array([[b[s]["worlds"][w] for s in steps] for b in by])
        right.plot(x, np.median(per, 0), color=f"C{i}", label=w)
    if worlds:
        right.set(xlabel="environment steps", ylabel="median over seeds, per world")
        right.legend(fontsize=7, ncol=2)
    fig.suptitle(a.title or f"{len(a.runs)} training seeds of {scenario}")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(json.dumps({"out": a.out, "steps": steps, "median": np.median(score, 0).round(4).tolist(),
                      "min": score.min(0).round(4).tolist(), "max": score.max(0).round(4).tolist(),
                      "references": {k: round(v["sample"], 4) for k, v in refs.items()}}))


if __name__ == "__main__":
    main()
