"""``wfbench scenarios``: list the presets, show one as TOML, or import a user's sites and request log.

``wfbench scenarios import --sites sites.csv [--requests log.csv] --name NAME --out NAME.toml``
(also ``wfbench scenario import ...``) writes the scenario of
:func:`wfbench.scenarios.importer.from_files`. A malformed file is one line naming the file,
line and column, exit status 2, and nothing is written: the file is written to a
temporary name beside ``--out`` and renamed when complete.
"""

from __future__ import annotations

import argparse
import os
import tempfile

from wfbench.cli.common import UsageError, check_writable, resolve_scenario
from wfbench.core.layout import FacilityLayout

IMPORT_OPTIONS = ("sites", "requests", "import_name", "out", "base", "jitter")


def add_parser(sub) -> None:
    s = sub.add_parser("scenarios", aliases=["scenario"], help="list the presets, show one as TOML, or import "
                       "your own sites and request log (wfbench scenarios import --help)",
                       description="List the presets, show one as TOML (wfbench scenarios NAME), or import a "
                                   "scenario from your own files (wfbench scenarios import --sites ... --name ... "
                                   "--out ...; see docs/scenarios.md).")
    s.set_defaults(command="scenarios")  # under the alias too
    s.add_argument("name", nargs="?", help="a preset to show, or 'import'")
    g = s.add_argument_group("import (wfbench scenarios import)")
    g.add_argument("--sites", help="CSV: id, x and y (grid cells) or lat and lon (degrees), weight (optional)")
    g.add_argument("--requests", help="CSV request log: time (a step or an ISO 8601 timestamp), site (an id)")
    g.add_argument("--name", dest="import_name", metavar="NAME", help="the new scenario's name")
    g.add_argument("--out", help="the .toml or .json file to write")
    g.add_argument("--base", default=None, help="the scenario everything else comes from (default paper-64)")
    g.add_argument("--jitter", type=float, default=None, help="spread of facilities around a site, cells (default 0)")


def _import(args: argparse.Namespace) -> int:
    from wfbench.scenarios.importer import from_files

    for option, value in (("--sites", args.sites), ("--name", args.import_name), ("--out", args.out)):
        if not value:
            raise UsageError(f"scenarios import needs {option}; allowed: wfbench scenarios import --sites SITES.csv "
                             "[--requests LOG.csv] --name NAME --out NAME.toml [--base PRESET] [--jitter CELLS]")
    if not args.out.endswith((".toml", ".json")):
        raise UsageError(f"--out {args.out!r}: allowed: a file name ending in .toml or .json")
    out = check_writable(args.out, "--out")
    base = resolve_scenario(args.base or "paper-64")
    try:
        config = from_files(args.sites, args.requests, name=args.import_name, base=base,
                            jitter=0.0 if args.jitter is None else args.jitter)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=out.suffix)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(config.to_toml() if out.suffix == ".toml" else config.to_json())
        os.replace(tmp, out)
    except BaseException:
        os.unlink(tmp)
        raise
    sites = len(config.layout.sites)
    print(f"wrote {out}: scenario {config.name!r}, {sites} site(s) on {config.grid_width}x{config.grid_height}, "
          f"request_interval {config.request_interval:g}, request schedule {config.request_schedule.kind}")
    return 0


def run(args: argparse.Namespace) -> int:
    from wfbench.core.config import PRESETS

    if args.name == "import":
        return _import(args)
    given = [f"--{o.replace('import_', '')}" for o in IMPORT_OPTIONS if getattr(args, o) is not None]
    if given:
        raise UsageError(f"{', '.join(given)} apply to 'wfbench scenarios import' only")
    if args.name:
        print(resolve_scenario(args.name).to_toml(), end="")
        return 0
    print(f"{'name':<24s} {'grid':>9s} {'facilities':>12s} {'personnel':>11s} {'horizon':>8s}  layout")
    for name, c in PRESETS.items():
        print(f"{name:<24s} {c.grid_width:>4d}x{c.grid_height:<4d} {c.initial_facilities:>5d}/{c.max_facilities:<6d}"
              f" {c.initial_personnel:>4d}/{c.max_personnel:<6d} {c.horizon:>8d}  {_layout_cell(c.layout)}")
    return 0


def _layout_cell(layout: FacilityLayout) -> str:
    """The listing's layout column: the kind and the fields it reads, e.g. ``clustered (4 towns, spread 4)``."""
    if layout.kind == "clustered":
        return f"clustered ({layout.towns} towns, spread {layout.spread:g})"
    if layout.kind == "sites":
        return f"sites ({len(layout.sites)} sites, jitter {layout.jitter:g})"
    return layout.kind
