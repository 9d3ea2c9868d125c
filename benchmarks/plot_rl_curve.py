"""Learning curves of training runs (PPO, IMPALA, hindsight learning) from their TensorBoard scalars, as a PNG.

    python benchmarks/plot_rl_curve.py RUN_DIR [RUN_DIR ...] --out docs/img/rl-curve.png [--reference heuristic]

Top left: the training episodes' mean NSW (training seeds); top right: the mean NSW on
the public selection seeds (sampled, and greedy dashed) by environment steps, with the
reference policy (``--reference``, any policy name; the heuristic composite by default)
on the same seeds as a line; bottom left: the same by
wall-clock minutes since the run's start; bottom right: the workforce cost on the
public seeds. A run started with ``--init`` is drawn after the steps of the run it
started from. The selection seeds of the last run give the reference line.
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
from wfbench.core.seeds import resolve_seeds  # noqa: E402


def scalars(run: Path, offset: int = 0) -> dict[str, list[tuple[int, float, float]]]:
    """tag -> [(environment step, value, wall-clock seconds since the run's first event)]."""
    ea = EventAccumulator(str(run / "tb"), size_guidance={"scalars": 0})
    ea.Reload()
    tags = ea.Tags()["scalars"]
    t0 = min((ea.Scalars(t)[0].wall_time for t in tags if ea.Scalars(t)), default=0.0)
    out = {tag: [(e.step + offset, e.value, e.wall_time - t0) for e in ea.Scalars(tag)] for tag in tags}
    # staggered runs log several episodes per update: one mean per update
    for tag in [t for t in out if t.startswith("episode/")]:
        by: dict[int, list[tuple[float, float]]] = {}
        for step, v, w in out[tag]:
            by.setdefault(step, []).append((v, w))
        out[tag] = [(k, sum(v for v, _ in vs) / len(vs), vs[-1][1]) for k, vs in sorted(by.items())]
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
    ap.add_argument("--reference", default="heuristic", help="the policy drawn as a line, on the same seeds")
    a = ap.parse_args()
    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    for i, run in enumerate(map(Path, a.runs)):
        color = f"C{i}"
        cfg = json.loads((run / "config.json").read_text())
        s = scalars(run, init_offset(cfg))
        agents = " independent agents" if cfg.get("agents") == "independent" else ""
        label = f"{cfg.get('algo', 'ppo')} {cfg['variant']}{agents} ({cfg['model']}, {run.name})"
        if "episode/nsw" in s:
            steps, values, _ = zip(*s["episode/nsw"], strict=True)
            axes[0, 0].plot(steps, values, color=color, lw=1, label=label)
        if "public/nsw_sample" in s:
            steps, values, wall = zip(*s["public/nsw_sample"], strict=True)
            axes[0, 1].plot(steps, values, marker="o", ms=3, color=color, label=f"{label} sampled")
            axes[1, 0].plot([w / 60 for w in wall], values, marker="o", ms=3, color=color, label=label)
        if "public/nsw_greedy" in s:
            steps, values, _ = zip(*s["public/nsw_greedy"], strict=True)
            axes[0, 1].plot(steps, values, ls="--", marker="x", ms=3, color=color, alpha=0.5)
        if "public/workforce_cost_sample" in s:
            steps, values, _ = zip(*s["public/workforce_cost_sample"], strict=True)
            axes[1, 1].plot(steps, values, marker="o", ms=3, color=color, label=label)
    seeds = resolve_seeds(cfg["eval_seeds"])
    ref = wfbench.evaluate(a.reference, cfg["scenario"], seeds)
    for ax in (axes[0, 1], axes[1, 0]):
        ax.axhline(ref["nsw"].mean(), color="grey", ls=":", label=f"{a.reference} (same seeds)")
    axes[1, 1].axhline(ref["workforce_cost"].mean(), color="grey", ls=":", label=a.reference)
    axes[0, 0].set_title("training episodes (train seeds)")
    axes[0, 1].set_title(f"selection seeds ({cfg['eval_seeds']}); greedy dashed")
    axes[1, 0].set_title("selection seeds, by wall-clock (shared 2-core VM)")
    axes[1, 1].set_title("workforce cost on the selection seeds")
    for ax in (axes[0, 0], axes[0, 1], axes[1, 0]):
        ax.set_ylabel("mean NSW (higher is better)")
    axes[1, 1].set_ylabel("workforce cost")
    for ax in (axes[0, 0], axes[0, 1], axes[1, 1]):
        ax.set_xlabel("environment steps")
    axes[1, 0].set_xlabel("minutes since the run's start")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    axes[0, 1].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7)
    fig.suptitle(f"Learning curves on {cfg['scenario']}")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
