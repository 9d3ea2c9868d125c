"""``wfbench policies``: every registered policy, grouped by family, with its decisions and measured budget class.

One line per policy: its name, how it is built, its summary, how tables name its dispatch,
workforce and positioning, and its budget class (the CPU ms per env-step it was measured
at in ``docs/results/frontier-v1/``, or "not measured"). ``--family NAME`` lists one family;
``--format json`` prints the same as a JSON list for tools. The rows are the registry's one
table (:mod:`wfbench.policies.table`); ``docs/policies.md``, "Listing policies".
"""

from __future__ import annotations

import argparse
import dataclasses
import json

from wfbench.cli.common import UsageError


def add_parser(sub) -> None:
    p = sub.add_parser("policies", help="list the registered policies by family, lookaheads and oracles included",
                       description="List every registered policy, grouped by family, with its decisions and "
                                   "measured budget class (docs/policies.md, \"Listing policies\").")
    p.add_argument("--family", default=None, metavar="NAME",
                   help="only this family: composite, tuned, learned, rollout, mpc, search or oracle")
    p.add_argument("--format", default="text", choices=["text", "json"], help="output format (default text)")


def _row(e, shipped: bool) -> dict:
    """An entry as JSON: its fields, its recipe by type, its decisions by name, whether it can be built here."""
    from wfbench.policies.registry import parts

    dispatch, workforce, positioning = parts(e.name)
    return {"name": e.name, "family": e.family, "kind": e.kind, "summary": e.summary,
            "built": e.recipe.describe(), "recipe": {"type": type(e.recipe).__name__, **dataclasses.asdict(e.recipe)},
            "decisions": {"dispatch": dispatch, "workforce": workforce, "positioning": positioning},
            "reads_future": e.reads_future, "listed": e.listed, "oracle_candidate": e.oracle_candidate,
            "candidate_of": list(e.candidate_of), "budget": e.budget_class, "available": shipped}


def run(args: argparse.Namespace) -> int:
    from wfbench.policies import DECISIONS
    from wfbench.policies.registry import entries, learned_names, parts, seed_members, seed_runs, shipped_member
    from wfbench.policies.table import FAMILIES

    try:
        rows = entries(args.family)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    shipped = set(learned_names())
    available = {e.name: e.kind != "learned" or e.name in shipped for e in rows}
    if args.format == "json":
        print(json.dumps([_row(e, available[e.name]) for e in rows], indent=1))
        return 0
    runs = seed_runs()
    for family, what in FAMILIES.items():
        group = [e for e in rows if e.family == family]
        if not group:
            continue
        print(f"[{family}] {what}")
        for e in group:
            note = "" if available[e.name] else " (its checkpoint is not shipped here)"
            print(f"{e.name:<22s} {e.recipe.describe()}: {e.summary}{note}; decisions: {' | '.join(parts(e.name))}; "
                  f"budget: {e.budget_class}")
            present = seed_members(e.name) if e.name in runs else []
            if present:  # training seeds: reported by their aggregate (docs/suite.md)
                pick = shipped_member(e.name)
                print(f"{e.name + '#seedK':<22s} the training seeds of {e.name}: {', '.join(present)} "
                      f"({len(present)} of {len(runs[e.name])} trained); its shipped pick is "
                      + (pick.rpartition("#")[2] if pick else "none of them")
                      + "; wfbench reproduce suite reports the method over its seeds (docs/suite.md)")
        print()
    if args.family in (None, "composite"):
        for decision, table in DECISIONS.items():
            print(f"{decision} decisions (for Composite, D+W+P and fixed agents): {', '.join(table)}")
    return 0
