"""``wfbench suite``: list the scenario suites, or show one with its split, hash, reasons and reference constants."""

from __future__ import annotations

import argparse
import json

from wfbench.cli.common import UsageError


def add_parser(sub) -> None:
    s = sub.add_parser("suite", help="list the scenario suites, or show one (scenarios, split, hash, constants)")
    action = s.add_subparsers(dest="suite_action", required=True, metavar="{list,show}")
    action.add_parser("list", help="the suites, their version, size and hash")
    show = action.add_parser("show", help="one suite: its scenarios, split, why each is there, reference constants")
    show.add_argument("name", help="a suite name (see 'wfbench suite list')")
    show.add_argument("--format", default="table", choices=["table", "md", "json"], help="output format")


def _suite(name: str):
    from wfbench.scenarios import get_suite

    try:
        return get_suite(name)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from wfbench.analysis.tables import markdown_table, text_table
    from wfbench.scenarios import SUITES, references

    if args.suite_action == "list":
        rows = [[s.name, str(s.version), str(len(s.ids("train"))), str(len(s.ids("heldout"))), s.hash, s.description]
                for s in (_suite(n) for n in SUITES)]
        print(text_table(["suite", "version", "train", "heldout", "hash", "description"], rows))
        return 0
    s = _suite(args.name)
    refs = references(s)
    consts = refs["scenarios"]
    if args.format == "json":
        print(json.dumps({"name": s.name, "version": s.version, "hash": s.hash, "description": s.description,
                          "public_seeds": list(s.public_seeds), "test_seeds": list(s.test_seeds),
                          "references": {k: refs[k] for k in ("seeds", "wfbench_version", "made_by")},
                          "scenarios": [{"id": sc.id, "preset": sc.preset, "version": sc.version, "split": sc.split,
                                         "hash": sc.hash, "why": sc.why, **{k: consts.get(sc.id, {}).get(k)
                                                                           for k in ("random_ref", "bound_ref")}}
                                        for sc in s.scenarios]}, indent=2))
        return 0

    def const(sc, key: str) -> str:
        entry = consts.get(sc.id)
        if entry is None:
            return "missing"
        return f"{entry[key]:.4f}" if entry["hash"] == sc.hash else "stale"

    header = ["scenario", "split", "random_ref", "bound_ref", "hash", "why"]
    rows = [[sc.id, sc.split, const(sc, "random_ref"), const(sc, "bound_ref"), sc.hash, sc.why] for sc in s.scenarios]
    print(f"{s.name} (version {s.version}, hash {s.hash}): {s.description}")
    print(f"train: tune and train on public seeds {s.public_seeds[0]}-{s.public_seeds[-1]} only; heldout: never "
          f"trained or tuned on; reported numbers on test seeds {s.test_seeds[0]}-{s.test_seeds[-1]}.\n")
    print((markdown_table if args.format == "md" else text_table)(header, rows))
    print(f"\nnormalized score = (NSW - random_ref) / (bound_ref - random_ref): random_ref is the random policy's "
          f"mean NSW, bound_ref the mean proven bound over seeds {refs['seeds'][0]}-{refs['seeds'][-1]} "
          f"(wfbench {refs['wfbench_version']}, {refs['made_by']}).")
    return 0
