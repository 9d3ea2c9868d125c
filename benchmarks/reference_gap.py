"""How far a replaying reference is from the bound and above every deployable policy, per world, from committed pieces.

Reads ``docs/results/reference-v2`` (the campaign's pieces, v2's and v3's) and then
``docs/results/suite-v1-50`` (the suite's, the bound's and the compiled candidates'); plays
nothing. Per world, for the reference's oracle (``--reference``, default v2: ``oracle-v2``): the
mean NSW of the bound, of ``oracle`` (v1) and of the oracle on the seeds its piece holds, the gap
(the bound's mean minus the oracle's), the best deployable candidate's mean, ``oracle-rollout``'s,
and the seed-by-seed checks: candidate seeds above the oracle, its seeds above the bound, and the
seeds where it is above each older reference with the candidate that gave them; and the deployable
policies with a piece that it does not play (a method's training seeds ``#seedK``, policies
registered after it), the best of them and those whose mean is above its own. docs/hindsight.md,
"How far the references are from the bound".

    python benchmarks/reference_gap.py novice-64-v1 churn-64-v1
    python benchmarks/reference_gap.py --reference v3 novice-64-v1
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from wfbench.policies.oracle.references import ORACLES, REFERENCES, REPLAYING
from wfbench.policies.registry import deployable_names, entry, lookahead_names, parse_member, seed_members, seed_runs

from wfbench.reproduce.suite import outside_oracle
from wfbench.scenarios.pieces import first_piece

ROOT = Path(__file__).resolve().parents[1]
RUNS = tuple(ROOT / "docs/results" / run for run in ("reference-v2", "suite-v1-50"))


def piece(policy: str, world: str) -> pd.DataFrame | None:
    """The first committed piece of ``policy`` on ``world`` in :data:`RUNS`, by seed; None where none is."""
    return first_piece(RUNS, policy, world)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("worlds", nargs="+", help="scenario ids of the suite with a piece of the reference's oracle")
    ap.add_argument("--reference", default="v2", help=f"a replaying reference: {', '.join(sorted(REPLAYING))} "
                    "(default v2)")
    args = ap.parse_args()
    if args.reference not in REPLAYING:
        raise SystemExit(f"reference_gap: --reference {args.reference} is not a replaying reference; allowed: "
                         f"{', '.join(sorted(REPLAYING))}")
    ref = args.reference
    name = next(n for n, r in ORACLES.items() if r == ref)
    older = [n for n, r in ORACLES.items() if n not in ("oracle", name) and r < ref]  # v2 under v3
    print(f"| scenario | seeds | bound | `oracle` (v1) | {''.join(f'`{n}` | ' for n in older)}`{name}` | "
          f"gap of {ref} | best deployable candidate | `oracle-rollout` |")
    print(f"|---|---:|---:|---:|{'---:|' * len(older)}---:|---:|---|---:|")
    notes = []
    for w in args.worlds:
        ours = piece(name, w)
        if ours is None:
            raise SystemExit(f"reference_gap: no {name} piece of {w}; allowed: a world the campaign finished")
        seeds = ours.index
        o, bound = ours["nsw"], piece("bound", w)["nsw"].reindex(seeds)
        refs = {n: p["nsw"].reindex(seeds) for n in ("oracle", *older) if (p := piece(n, w)) is not None}
        cands = {c: p["nsw"].reindex(seeds) for c in REFERENCES[ref] if (p := piece(c, w)) is not None}
        missing = [c for c in REFERENCES[ref] if c not in cands]
        deployable = {c: s.mean() for c, s in cands.items() if not entry(method_of(c)).reads_future}
        best = max(deployable, key=deployable.get)
        rollout = cands.get("oracle-rollout")
        print(f"| `{w}` | {len(seeds)} | {bound.mean():.4f} | "
              f"{''.join('-' if (x := refs.get(n)) is None else f'{x.mean():.4f}' for n in ('oracle',))} | "
              f"{''.join(('-' if (x := refs.get(n)) is None else f'{x.mean():.4f}') + ' | ' for n in older)}"
              f"{o.mean():.4f} | {bound.mean() - o.mean():.4f} | `{best}` ({deployable[best]:.4f}) | "
              f"{'-' if rollout is None else f'{rollout.mean():.4f}'} |")
        above = sum(int((s > o + 1e-12).sum()) for s in cands.values())
        over = int((o > bound + 1e-9).sum())
        gains = []
        for n, x in refs.items():
            won = [f"seed {s}: {', '.join(c for c, y in cands.items() if abs(y[s] - o[s]) < 1e-12)}"
                   for s in seeds[o > x + 1e-12]]
            gains.append(f"{ref} above {ORACLES[n]} on {len(won)} ({'; '.join(won) or 'none'})")
        others = {n: x.mean() for n in outside(w, name) if (x := piece(n, w)["nsw"].reindex(seeds)).notna().all()}
        top = max(others, key=others.get) if others else None
        beyond = [f"{n} ({m:.4f})" for n, m in sorted(others.items(), key=lambda nm: -nm[1]) if m > o.mean()]
        notes.append(f"{w}: candidate seeds above {name}: {above}; {name} seeds above the bound: {over}; "
                     f"{'; '.join(gains)}; candidates without a piece "
                     f"(compiled, played by the oracle itself): {', '.join(missing) or 'none'}; deployable policies "
                     f"it does not play, with a piece of these seeds: {len(others)}, the best "
                     f"{'-' if top is None else f'{top} ({others[top]:.4f})'}, above {ref}'s mean: "
                     f"{', '.join(beyond) or 'none'}")
    print()
    print("\n".join(notes))


def method_of(candidate: str) -> str:
    """A candidate's table entry: its method for a training seed (``METHOD#seedK``, a candidate from v3 on)."""
    member = parse_member(candidate)
    return candidate if member is None else member[0]


def outside(world: str, oracle: str) -> list[str]:
    """The registry's deployable policies and training seeds (``METHOD#seedK``) with a committed piece of ``world``
    that ``oracle`` does not play (``wfbench.reproduce.suite.outside_oracle``)."""
    members = [m for method in seed_runs() for m in seed_members(method)]
    names = (*deployable_names(), *lookahead_names(), *members)
    return [n for n in names if outside_oracle(n, oracle) and piece(n, world) is not None]


if __name__ == "__main__":
    main()
