"""The learning curve of a PPO run, from its TensorBoard scalars, as a PNG (docs/img/rl-curve.png).

    python benchmarks/plot_rl_curve.py RUN_DIR [RUN_DIR ...] --out docs/img/rl-curve.png

Left: the training episodes' mean NSW (training seeds); right: the mean NSW on the
public selection seeds, sampled and greedy, with the heuristic composite on the same
seeds as a reference line. Workforce cost below each.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator  # noqa: E402

import wfbench  # noqa: E402
from wfbench.seeds import resolve_seeds  # noqa: E402


def scalars(run: Path) -> dict[str, list[tuple[int, float]]]:
    ea = EventAccumulator(str(run / "tb"), size_guidance={"scalars": 0})
    ea.Reload()
    return {tag: [(e.step, e.value) for e in ea.Scalars(tag)] for tag in ea.Tags()["scalars"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--out", default="docs/img/rl-curve.png")
    a = ap.parse_args()
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for run in map(Path, a.runs):
        cfg = json.loads((run / "config.json").read_text())
        s = scalars(run)
        label = f"{cfg['variant']} ({cfg['model']})"
        for col, (tag, wtag) in enumerate((("episode/nsw", "episode/workforce_cost"),
                                           ("public/nsw_sample", "public/workforce_cost_sample"))):
            if tag in s:
                axes[0, col].plot(*zip(*s[tag], strict=True), marker="o", ms=3, label=f"{label} sampled"
                                  if col else label)
            if wtag in s:
                axes[1, col].plot(*zip(*s[wtag], strict=True), marker="o", ms=3, label=label)
        if "public/nsw_greedy" in s:
            axes[0, 1].plot(*zip(*s["public/nsw_greedy"], strict=True), ls="--", marker="x", ms=3,
                            label=f"{label} greedy")
        seeds = resolve_seeds(cfg["eval_seeds"])
        ref = wfbench.evaluate("heuristic", cfg["scenario"], seeds, backend="serial")
        axes[0, 1].axhline(ref["nsw"].mean(), color="grey", ls=":", label="heuristic (same seeds)")
        axes[1, 1].axhline(ref["workforce_cost"].mean(), color="grey", ls=":", label="heuristic")
    axes[0, 0].set_title("training episodes (train seeds)")
    axes[0, 1].set_title(f"selection seeds ({cfg['eval_seeds']})")
    axes[0, 0].set_ylabel("mean NSW (higher is better)")
    axes[1, 0].set_ylabel("workforce cost")
    for ax in axes[1]:
        ax.set_xlabel("environment steps")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"PPO on {cfg['scenario']}")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
