"""``wfbench compare``: several policies on the same seeds, paired differences to a baseline.

On one scenario (``--scenario``), or over a suite (``--suite``): paired per scenario, then aggregated per split.
"""

from __future__ import annotations

import argparse
import sys

from wfbench.cli.common import (
    UsageError,
    add_run_args,
    check_backend_args,
    check_suite_args,
    positive,
    resolve_scenario,
    seed_list,
)


def add_parser(sub) -> None:
    c = sub.add_parser("compare", help="several policies on the same seeds, paired differences to a baseline")
    c.add_argument("--policies", required=True, help="comma-separated registry names or module:attr entry points")
    c.add_argument("--baseline", default="heuristic", help="policy the paired differences are taken to")
    add_run_args(c)
    c.set_defaults(scenario=None)  # None: not given (paper-64), so that --scenario beside --suite is caught
    c.add_argument("--suite", default=None, help="compare over every scenario of a suite (see 'wfbench suite "
                   "list'): paired per scenario, then the aggregate per split with the probability of improvement")
    c.add_argument("--split", default=None, help="with --suite: only the train or the heldout scenarios")
    c.add_argument("--poi-reps", type=positive, default=1000, metavar="N", help="with --suite: bootstrap "
                   "replications of the probability of improvement's interval (default 1000; each costs a "
                   "Mann-Whitney U test per scenario)")
    c.add_argument("--format", default="table", choices=["table", "md", "csv"], help="output format")
    c.add_argument("--plot", default=None, metavar="PATH", help="also draw the KPIs per policy and the paired "
                   "NSW differences with their intervals into this .png, .svg or .pdf file")
    c.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: wfbench.harness.compare loads scipy.stats (wfbench.analysis.stats), which
    # took the warm start of 'wfbench evaluate --seeds 1' from 1.8 to 2.7 s of CPU (/usr/bin/time)
    from wfbench.core.seeds import describe
    from wfbench.harness.compare import check_plot_path, compare, format_comparison, plot_comparison
    from wfbench.harness.guard import PolicyLoadError

    names = [n.strip() for n in args.policies.split(",") if n.strip()]
    if not names:
        raise UsageError("--policies: give at least one policy name")
    if args.suite is not None or args.split is not None:
        return run_suite(args, names)
    config = resolve_scenario(args.scenario or "paper-64")
    execution = check_backend_args(args, progress=not args.no_progress)
    plot = None
    if args.plot:  # checked before the runs, which may take long
        try:
            plot = check_plot_path(args.plot, "--plot")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    seeds = seed_list(args)
    try:  # compare loads every policy before running the first
        df = compare(names, config, seeds, baseline=args.baseline, act_timeout_s=args.act_timeout,
                     execution=execution)
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


def run_suite(args: argparse.Namespace, names: list[str]) -> int:
    from wfbench.analysis.aggregate import AGGREGATE_NOTE, aggregate_cells
    from wfbench.analysis.tables import markdown_table, text_table
    from wfbench.core.seeds import describe
    from wfbench.harness.compare import compare_suite, format_suite_comparison
    from wfbench.harness.guard import PolicyLoadError

    if args.suite is not None and args.plot:
        raise UsageError("--plot applies to one scenario, not to --suite ('wfbench reproduce suite' draws the "
                         "suite's figures)")
    suite = check_suite_args(args)
    execution = check_backend_args(args, progress=not args.no_progress)
    seeds = seed_list(args)
    try:
        result = compare_suite(names, suite, seeds, baseline=args.baseline, split=args.split,
                               act_timeout_s=args.act_timeout, poi_reps=args.poi_reps, execution=execution)
    except PolicyLoadError as exc:
        raise UsageError(str(exc)) from None
    if result.baseline_added:
        print(f"wfbench: note: the baseline {args.baseline!r} is not in --policies; added it as the first row "
              "(choose another with --baseline)", file=sys.stderr)
    text = format_suite_comparison(result, args.format)
    if args.format == "csv":
        print(text, end="")
        return 0
    table = markdown_table if args.format == "md" else text_table
    print(text)
    print(f"{suite.name} (hash {suite.hash}), seeds {describe(seeds)}: means over seeds; normalized = "
          "(NSW - random) / (bound - random); differences of the normalized score, paired by seed.\n")
    print(table(*aggregate_cells(result.aggregates)))
    print(AGGREGATE_NOTE + " P(improvement): the probability that the policy beats the baseline on a random "
          "scenario of the split and a random pair of runs (rliable).")
    return 0
