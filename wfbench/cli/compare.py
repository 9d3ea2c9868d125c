"""``wfbench compare``: several policies on the same seeds, paired differences to a baseline."""

from __future__ import annotations

import argparse
import sys

from wfbench.cli.common import (
    UsageError,
    add_run_args,
    check_backend_args,
    check_writable,
    resolve_scenario,
    seed_list,
)


def add_parser(sub) -> None:
    c = sub.add_parser("compare", help="several policies on the same seeds, paired differences to a baseline")
    c.add_argument("--policies", required=True, help="comma-separated registry names or module:attr entry points")
    c.add_argument("--baseline", default="heuristic", help="policy the paired differences are taken to")
    add_run_args(c)
    c.add_argument("--format", default="table", choices=["table", "md", "csv"], help="output format")
    c.add_argument("--plot", default=None, metavar="PATH", help="also draw the KPIs per policy and the paired "
                   "NSW differences with their intervals into this .png, .svg or .pdf file")
    c.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: wfbench.compare loads scipy.stats (wfbench.stats), which
    # took the warm start of 'wfbench evaluate --seeds 1' from 1.8 to 2.7 s of CPU (/usr/bin/time)
    from wfbench.compare import compare, format_comparison, plot_comparison
    from wfbench.core.seeds import describe
    from wfbench.guard import PolicyLoadError
    from wfbench.plots import figure_format

    config = resolve_scenario(args.scenario)
    names = [n.strip() for n in args.policies.split(",") if n.strip()]
    if not names:
        raise UsageError("--policies: give at least one policy name")
    check_backend_args(args)
    plot = None
    if args.plot:  # checked before the runs, which may take long
        try:
            figure_format(args.plot)
        except ValueError as exc:
            raise UsageError(f"--plot: {exc}") from None
        plot = check_writable(args.plot, "--plot")
        if plot.is_dir():
            raise UsageError(f"--plot {args.plot!r} is a folder; give a file name")
    seeds = seed_list(args)
    try:  # compare loads every policy before running the first
        df = compare(names, config, seeds, baseline=args.baseline, backend=args.backend, workers=args.workers,
                     address=args.address, progress=not args.no_progress, act_timeout_s=args.act_timeout)
    except PolicyLoadError as exc:
        raise UsageError(str(exc)) from None
    if df.attrs["baseline_added"]:  # on stderr: a CSV on stdout stays clean
        print(f"wfbench: note: the baseline {args.baseline!r} is not in --policies; added it as the first row "
              "(choose another with --baseline)", file=sys.stderr)
    text = format_comparison(df, args.format)
    print(text, end="" if text.endswith("\n") else "\n")  # a CSV ends with its own newline
    if args.format != "csv":
        print(f"{config.name}, seeds {describe(seeds)}: KPIs mean (25%-75%); NSW higher is "
              f"better; intervals are bootstrap 95% over seeds, differences paired by seed.")
    if plot:
        try:
            plot_comparison(df, plot)
        except OSError as exc:
            raise UsageError(f"--plot: cannot write {str(plot)!r}: {exc.strerror or exc}") from None
        print(f"wrote {plot}", file=sys.stderr)  # on stderr: a CSV on stdout stays clean
    return 0
