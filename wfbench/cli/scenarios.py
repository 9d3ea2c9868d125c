"""``wfbench scenarios``: list the presets, or show one as TOML."""

from __future__ import annotations

import argparse

from wfbench.cli.common import resolve_scenario


def add_parser(sub) -> None:
    s = sub.add_parser("scenarios", help="list the presets, or show one as TOML")
    s.add_argument("name", nargs="?", help="a preset to show")


def run(args: argparse.Namespace) -> int:
    from wfbench.core.config import PRESETS

    if args.name:
        print(resolve_scenario(args.name).to_toml(), end="")
        return 0
    print(f"{'name':<24s} {'grid':>9s} {'facilities':>12s} {'personnel':>11s} {'horizon':>8s}")
    for name, c in PRESETS.items():
        print(f"{name:<24s} {c.grid_width:>4d}x{c.grid_height:<4d} {c.initial_facilities:>5d}/{c.max_facilities:<6d}"
              f" {c.initial_personnel:>4d}/{c.max_personnel:<6d} {c.horizon:>8d}")
    return 0
