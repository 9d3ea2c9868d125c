"""How far ``oracle-v2`` is from the bound and above every deployable policy, per world, from committed pieces.

Reads ``docs/results/reference-v2`` (the campaign's pieces) and then ``docs/results/suite-v1-50``
(the suite's, the bound's and the compiled candidates'); plays nothing. Per world: the mean NSW
of the bound, of ``oracle`` (v1) and of ``oracle-v2`` on the seeds ``oracle-v2``'s piece holds,
the gap (the bound's mean minus v2's), the best deployable candidate's mean, ``oracle-rollout``'s,
and the seed-by-seed checks: candidate seeds above v2, v2's seeds above the bound, and the seeds
where v2 is above v1 with the candidate that gave them; and the deployable policies with a piece
that v2 does not play (a method's training seeds ``#seedK``, policies registered after it), the
best of them and those whose mean is above v2's. docs/hindsight.md, "How far the references are
from the bound".

    python benchmarks/reference_gap.py novice-64-v1 churn-64-v1
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from wfbench.policies.oracle.references import V2
from wfbench.policies.registry import deployable_names, entry, lookahead_names, seed_runs

from wfbench.scenarios.pieces import first_piece

ROOT = Path(__file__).resolve().parents[1]
RUNS = tuple(ROOT / "docs/results" / run for run in ("reference-v2", "suite-v1-50"))


def piece(policy: str, world: str) -> pd.DataFrame | None:
    """The first committed piece of ``policy`` on ``world`` in :data:`RUNS`, by seed; None where none is."""
    return first_piece(RUNS, policy, world)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("worlds", nargs="+", help="scenario ids of the suite with an oracle-v2 piece")
    args = ap.parse_args()
    print("| scenario | seeds | bound | `oracle` (v1) | `oracle-v2` | gap of v2 | best deployable candidate | "
          "`oracle-rollout` |")
    print("|---|---:|---:|---:|---:|---:|---|---:|")
    notes = []
    for w in args.worlds:
        v2 = piece("oracle-v2", w)
        if v2 is None:
            raise SystemExit(f"reference_gap: no oracle-v2 piece of {w}; allowed: a world the campaign finished")
        seeds = v2.index
        o, v1, bound = v2["nsw"], piece("oracle", w)["nsw"].reindex(seeds), piece("bound", w)["nsw"].reindex(seeds)
        cands = {c: p["nsw"].reindex(seeds) for c in V2 if (p := piece(c, w)) is not None}
        missing = [c for c in V2 if c not in cands]
        deployable = {c: s.mean() for c, s in cands.items() if not entry(c).reads_future}
        best = max(deployable, key=deployable.get)
        rollout = cands.get("oracle-rollout")
        print(f"| `{w}` | {len(seeds)} | {bound.mean():.4f} | {v1.mean():.4f} | {o.mean():.4f} | "
              f"{bound.mean() - o.mean():.4f} | `{best}` ({deployable[best]:.4f}) | "
              f"{'-' if rollout is None else f'{rollout.mean():.4f}'} |")
        above = sum(int((s > o + 1e-12).sum()) for s in cands.values())
        over = int((o > bound + 1e-9).sum())
        gains = [f"seed {s}: {', '.join(c for c, x in cands.items() if abs(x[s] - o[s]) < 1e-12)}"
                 for s in seeds[o > v1 + 1e-12]]
        others = {n: x.mean() for n in outside(w) if (x := piece(n, w)["nsw"].reindex(seeds)).notna().all()}
        top = max(others, key=others.get) if others else None
        beyond = [f"{n} ({m:.4f})" for n, m in sorted(others.items(), key=lambda nm: -nm[1]) if m > o.mean()]
        notes.append(f"{w}: candidate seeds above oracle-v2: {above}; oracle-v2 seeds above the bound: {over}; "
                     f"v2 above v1 on {len(gains)} ({'; '.join(gains) or 'none'}); candidates without a piece "
                     f"(compiled, played by the oracle itself): {', '.join(missing) or 'none'}; deployable policies "
                     f"it does not play, with a piece of these seeds: {len(others)}, the best "
                     f"{'-' if top is None else f'{top} ({others[top]:.4f})'}, above v2's mean: "
                     f"{', '.join(beyond) or 'none'}")
    print()
    print("\n".join(notes))


def outside(world: str) -> list[str]:
    """The registry's deployable policies and training seeds (``METHOD#seedK``) with a committed piece of ``world``
    that ``oracle-v2`` does not play."""
    members = [f"{m}#seed{k}" for m, files in seed_runs().items() for k in range(len(files))]
    names = (*deployable_names(), *lookahead_names(), *members)
    return [n for n in names if n not in V2 and piece(n, world) is not None]


if __name__ == "__main__":
    main()
