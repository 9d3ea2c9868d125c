"""A world and its twins in other units (issue #32): lengths, speed and spatial spread times k, every policy scored.

A world whose grid side, speed and ``heat_sigma`` are all multiplied by k is the same
world in other units (``wfbench.core.observation_v2.scaled_world``). A policy that reads the
world as a dispatcher does scores the same on both, up to the discretization of the grid
(facilities sit on whole cells). For each world, each policy and k in ``--ks``, the mean
NSW over the seeds; then per policy the largest move from k = 1, and for a method with
training seeds (``METHOD#seedK``) the spread of its seeds at k = 1 beside the move of
their mean. Worlds with fixed facility sites (``clustered-64``, the real-data ones) are
left out: their sites are in cells.

Writes ``scale-twins.csv`` (one row per policy, world and k, written as each is scored: a
stopped run resumes from it, and a later call with more policies scores only the new ones)
and ``scale-twins.md`` (the policies of this call) into ``--out``. Usage::

    python benchmarks/scale_twins.py --seeds 0-9 --out docs/results/scale-twins
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import pandas as pd
from wfbench.policies.registry import parse_member, seed_members

from wfbench.analysis.tables import markdown_table
from wfbench.core.config import ScenarioConfig
from wfbench.core.observation_v2 import scaled_world
from wfbench.core.seeds import describe, resolve_seeds
from wfbench.harness.backends import Execution
from wfbench.harness.budget import machine, machine_line
from wfbench.harness.evaluation import evaluate
from wfbench.scenarios import get_suite

WORLDS = ("small-v1", "paper-64-v1", "table2-g32-f25-s10-v1", "slow-64-v1", "churn-64-v1",
          "table2-g32-f100-s25-v1")
POLICIES = ("heuristic", "solver-tuned", "ppo-general", "hindsight-general", "scalefree-general")


def world(sid: str) -> ScenarioConfig:
    return get_suite("suite-v1").scenario(sid).config


def expand(policies: list[str], members: set[str]) -> list[str]:
    """A method of ``members`` stands for its training seeds (``METHOD#seedK``); any other policy for itself."""
    out = []
    for p in policies:
        out.extend((seed_members(p) if p in members else []) or [p])
    return out


def md(df: pd.DataFrame) -> str:
    return markdown_table(list(df.columns), [[f"{v:.4f}" if isinstance(v, float) else str(v) for v in row]
                                             for row in df.itertuples(index=False)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default=",".join(WORLDS))
    ap.add_argument("--policies", default=",".join(POLICIES))
    ap.add_argument("--members", default="scalefree-general",
                    help="methods played as each of their training seeds (the others: their shipped pick)")
    ap.add_argument("--ks", default="1,2,4")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="scale-twins")
    a = ap.parse_args()
    seeds = resolve_seeds(a.seeds)
    ks = [float(k) for k in a.ks.split(",")]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / "scale-twins.csv"
    done = pd.read_csv(csv).to_dict("records") if csv.exists() else []
    have = {(r["world"], float(r["k"]), r["policy"]): r for r in done if str(r.get("seeds")) == a.seeds}
    rows = []
    t0 = time.perf_counter()
    for sid in a.worlds.split(","):
        base = world(sid)
        for k in ks:
            config = base if k == 1 else scaled_world(base, k)
            for pol in expand(a.policies.split(","), set(a.members.split(","))):
                if (sid, k, pol) in have:
                    rows.append(have[(sid, k, pol)])
                    continue
                df = evaluate(pol, config, seeds, act_timeout_s=None,
                              execution=Execution(backend="process", workers=a.workers))
                member = parse_member(pol)
                row = {"world": sid, "k": k, "policy": pol, "method": member[0] if member else pol,
                       "nsw": float(df["nsw"].mean()), "seeds": a.seeds}
                rows.append(row)
                done.append(row)
                have[(sid, k, pol)] = row
                pd.DataFrame(done).to_csv(csv, index=False)
                print(f"{sid:24s} k={k:g}  {pol:28s} {row['nsw']:.4f}", flush=True)
    wall = time.perf_counter() - t0
    df = pd.DataFrame(rows)
    # per method and world: its mean over members at each k; the move from k = 1; the members' spread at k = 1
    per = df.groupby(["method", "world", "k"])["nsw"].agg(["mean", "min", "max", "count"]).reset_index()
    table = []
    for (method, sid), g in per.groupby(["method", "world"], sort=False):
        g = g.set_index("k")
        move = max(abs(g.loc[k, "mean"] - g.loc[1.0, "mean"]) for k in ks)
        spread = g.loc[1.0, "max"] - g.loc[1.0, "min"] if g.loc[1.0, "count"] > 1 else float("nan")
        table.append({"method": method, "world": sid, **{f"k={k:g}": g.loc[k, "mean"] for k in ks},
                      "largest move": move, "seeds' spread at k=1": spread})
    t = pd.DataFrame(table)
    summary = t.groupby("method", sort=False)[["largest move", "seeds' spread at k=1"]].mean().reset_index()
    text = (f"# A world and its twins at k = {', '.join(f'{k:g}' for k in ks)}\n\n"
            f"Mean NSW over seeds {describe(seeds)}; lengths, speed and heat_sigma times k "
            "(`wfbench.core.observation_v2.scaled_world`). A method with training seeds is the mean of its seeds; "
            "its spread is max - min of the seeds' means at k = 1.\n\n"
            f"Command: `python benchmarks/scale_twins.py --seeds {a.seeds} --ks {a.ks} --out {a.out}`; "
            f"{wall / 60:.1f} minutes on {machine_line(machine())}.\n\n"
            "## Per method, averaged over the worlds\n\n" + md(summary) + "\n\n"
            "## Per method and world\n\n" + md(t) + "\n")
    (out / "scale-twins.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
