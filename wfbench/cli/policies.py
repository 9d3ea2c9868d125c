"""``wfbench policies``: list the registered policies (lookaheads included) and the decisions of a composite."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    sub.add_parser("policies", help="list the registered policies, lookaheads included")


def run(args: argparse.Namespace) -> int:
    from wfbench.policies import DECISIONS
    from wfbench.policies.registry import (
        COMPOSITES,
        LEARNED,
        LOOKAHEAD,
        ORACLES,
        SEED_RUNS,
        TUNED,
        learned_names,
        lookahead_names,
        seed_members,
        shipped_member,
    )

    for name, (d, w, p, text) in COMPOSITES.items():
        print(f"{name:<22s} dispatch={d}, workforce={w}, positioning={p}: {text}")
    for name, text in ORACLES.items():
        print(f"{name:<22s} {text}")
    for name, (file, text) in TUNED.items():
        print(f"{name:<22s} policies/tuned/{file}: {text}")
    for name in learned_names():
        print(f"{name:<22s} policies/neural/checkpoints/{LEARNED[name][0]}: {LEARNED[name][1]}")
    for name in lookahead_names():  # deployable lookaheads: they plan on futures sampled from what they observed
        base, _, text = LOOKAHEAD[name]
        print(f"{name:<22s} a lookahead on {base}: {text}")
    for method, files in SEED_RUNS.items():  # training seeds: reported by their aggregate (docs/suite.md)
        present = seed_members(method)
        if not present:
            continue
        pick = shipped_member(method)
        print(f"{method + '#seedK':<22s} the training seeds of {method}: {', '.join(present)} ({len(present)} of "
              f"{len(files)} trained); its shipped pick is " + (pick.rpartition("#")[2] if pick else "none of them")
              + "; wfbench reproduce suite reports the method over its seeds (docs/suite.md)")
    for decision, table in DECISIONS.items():
        print(f"{decision} decisions (for Composite and fixed agents): {', '.join(table)}")
    return 0
