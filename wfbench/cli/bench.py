"""``wfbench bench``: measure environment steps per second (wfbench.harness.bench)."""

from __future__ import annotations

import argparse

from wfbench.cli.common import SCENARIO_HELP, check_writable, positive, resolve_scenario


def add_parser(sub) -> None:
    b = sub.add_parser("bench", help="measure env-steps per second")
    b.add_argument("--scenario", default="paper-64", help=f"{SCENARIO_HELP} (default paper-64)")
    b.add_argument("--quick", action="store_true", help="fewer and smaller measurements")
    b.add_argument("--json", default=None, help="also write the results to this JSON file")
    b.add_argument("--rounds", type=positive, default=None,
                   help="measure every row this many times, interleaved (default 3; 1 with --quick)")


def run(args: argparse.Namespace) -> int:
    from wfbench.harness.bench import run as run_bench

    config = resolve_scenario(args.scenario)
    if args.json:
        check_writable(args.json, "--json")
    run_bench(config, quick=args.quick, json_path=args.json, rounds=args.rounds)
    return 0
