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


def scalars(run: Path, offset: int = 0) -> dict[str, list[tuple[int, float]]]:
    ea = EventAccumulator(str(run / "tb"), size_guidance={"scalars": 0})
    ea.Reload()
    out = {tag: [(e.step + offset, e.value) for e in ea.Scalars(tag)] for tag in ea.Tags()["scalars"]}
    # staggered runs log several episodes per update: one mean per update
    for tag in [t for t in out if t.startswith("episode/")]:
        by: dict[int, list[float]] = {}
        for step, v in out[tag]:
            by.setdefault(step, []).append(v)
        out[tag] = [(k, sum(v) / len(v)) for k, v in sorted(by.items())]
    return out


def init_offset(cfg: dict) -> int:
    """A run started with --init continues the steps of the checkpoint it started from (and of its own start)."""
    if not cfg.get("init"):
        return 0
    import torch

    start = torch.load(cfg["init"], map_location="cpu", weights_only=False)
    return int(start["global_step"]) + init_offset(start["train_config"])  # a chain of --init runs adds up


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--out", default="docs/img/rl-curve.png")
    a = ap.parse_args()
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for i, run in enumerate(map(Path, a.runs)):
        color = f"C{i}"
        cfg = json.loads((run / "config.json").read_text())
        offset = init_offset(cfg)
        s = scalars(run, offset)
        label = f"{cfg['variant']} ({cfg['model']}, {run.name})"
        for col, (tag, wtag) in enumerate((("episode/nsw", "episode/workforce_cost"),
                                           ("public/nsw_sample", "public/workforce_cost_sample"))):
            if tag in s:
                axes[0, col].plot(*zip(*s[tag], strict=True), marker="o", ms=3, color=color,
                                  label=f"{label} sampled" if col else label)
            if wtag in s:
                axes[1, col].plot(*zip(*s[wtag], strict=True), marker="o", ms=3, color=color, label=label)
        if "public/nsw_greedy" in s:
            axes[0, 1].plot(*zip(*s["public/nsw_greedy"], strict=True), ls="--", marker="x", ms=3, color=color,
                            alpha=0.6, label=f"{label} greedy")
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
