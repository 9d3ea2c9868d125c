"""``wfbench evaluate``: score a policy over seeds, one Table 3 style row; or over a suite, a row per scenario."""

from __future__ import annotations

import argparse
import json
import sys

from wfbench.cli.common import (
    UsageError,
    add_run_args,
    check_backend_args,
    check_suite_args,
    check_writable,
    resolve_scenario,
    seed_list,
)


def add_parser(sub) -> None:
    e = sub.add_parser("evaluate", help="score a policy over seeds (Table 3 style row)")
    e.add_argument("--policy", required=True, help="registry name (see 'wfbench policies') or module:attr")
    add_run_args(e)
    e.set_defaults(scenario=None)  # None: not given (paper-64), so that --scenario beside --suite is caught
    e.add_argument("--suite", default=None, help="score every scenario of a suite instead of one scenario "
                   "(see 'wfbench suite list'): a row per scenario with its normalized score, then the aggregate "
                   "per split")
    e.add_argument("--split", default=None, help="with --suite: only the train or the heldout scenarios")
    e.add_argument("--format", default="table", choices=["table", "md", "csv", "json"], help="output format")
    e.add_argument("--out", default=None, help="also write the per-seed rows (per scenario and seed with "
                   "--suite) to this CSV file")
    e.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    e.add_argument("--sandbox", action="store_true", help="run the policy as a hosted board does: packed, in a "
                   "bubblewrap sandbox, seeing opaque keys instead of seeds; --policy is then a package folder (with "
                   "wfbench-policy.json), a .zip or .whl package, or module:attr (packed from the current folder); "
                   "one batch in this process (--backend does not apply)")


def run(args: argparse.Namespace) -> int:
    from wfbench.analysis.tables import markdown_table, text_table
    from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
    from wfbench.core.seeds import describe
    from wfbench.harness.evaluation import evaluate, format_kpi, summarize
    from wfbench.harness.guard import PolicyLoadError

    if args.suite is not None or args.split is not None:
        if args.sandbox:
            raise UsageError("--sandbox evaluates one scenario; it does not go with --suite or --split")
        return run_suite(args)
    config = resolve_scenario(args.scenario or "paper-64")
    execution = check_backend_args(args, progress=not args.no_progress)
    out = check_writable(args.out, "--out") if args.out else None
    seeds = seed_list(args)
    if args.sandbox:
        df = run_sandboxed(args.policy, config, seeds, args.act_timeout)
    else:
        try:  # evaluate loads the policy once; a spec that names none is a usage error
            df = evaluate(args.policy, config, seeds, act_timeout_s=args.act_timeout, execution=execution)
        except PolicyLoadError as exc:
            raise UsageError(str(exc)) from None
    if out:
        df.to_csv(out, index=False)
    summary = summarize(df)
    if args.format == "csv":
        df.to_csv(sys.stdout, index=False)
    elif args.format == "json":
        print(json.dumps({"policy": args.policy, "scenario": config.name, "seeds": seeds,
                          "summary": {k: dict(zip(("mean", "q25", "q75"), v, strict=True))
                                      for k, v in summary.items()}}, indent=2))
    else:
        header = ["Policy", *[KPI_LABELS[k] for k in KPI_NAMES]]
        rows = [[args.policy, *[format_kpi(*summary[k]) for k in KPI_NAMES]]]
        print((markdown_table if args.format == "md" else text_table)(header, rows))
        print(f"{config.name}, seeds {describe(seeds)}: mean (25%-75%) over seeds of the "
              "episode means; NSW higher is better.")
    return 0


def package_bytes(spec: str) -> bytes:
    """The package ``--policy`` names with --sandbox: a folder with a manifest, a .zip/.whl, or module:attr."""
    from pathlib import Path

    from wfbench.harness.isolation import package

    path = Path(spec)
    try:
        if path.is_dir():
            return package.pack_folder(path)
        if path.suffix in (".zip", ".whl"):
            if not path.is_file():
                raise UsageError(f"--policy: package {spec} does not exist")
            return path.read_bytes()
        if ":" in spec:
            return package.pack(spec, ".")
    except package.PackageError as exc:
        raise UsageError(f"--policy: {exc}") from None
    raise UsageError(f"--policy {spec!r} with --sandbox: allowed: a package folder (holding "
                     f"{package.MANIFEST}), a .zip or .whl package, or module:attr (packed from the current folder)")


def run_sandboxed(spec: str, config, seeds: list[int], act_timeout: float | None):
    """The rows of ``spec`` run as a hosted board runs it: packed, unpacked, in the sandbox, with opaque keys.

    The keys come from the public :data:`~wfbench.harness.isolation.sandbox.LOCAL_KEY_SECRET`: a local run
    has no seed to hide, and the same command gives the same keys.
    """
    import tempfile
    from pathlib import Path

    from wfbench.harness.isolation import package, sandbox

    data = package_bytes(spec)
    limits = sandbox.Limits(act_timeout_s=act_timeout or sandbox.Limits.wall_time_s)
    setup = "the sandbox cannot run on this machine (its set-up, not the policy)"
    try:
        sandbox.check_sandbox()
        with tempfile.TemporaryDirectory(prefix="wfbench-package-") as tmp:
            try:
                manifest = package.unpack(data, Path(tmp) / "package")
            except OSError as exc:  # a full disk, a temporary folder that cannot be written
                raise sandbox.SandboxUnavailable(f"the package could not be unpacked into {tmp}: "
                                                 f"{type(exc).__name__}: {exc}") from None
            df = sandbox.evaluate_sandboxed(Path(tmp) / "package", manifest.entry, config, seeds, limits,
                                            sandbox.LOCAL_KEY_SECRET, sandbox.LOCAL_KEY_CONTEXT)
    except sandbox.SandboxUnavailable as exc:
        reason = exc.reason.removeprefix("the sandbox could not start (the board's set-up, not the policy): ")
        raise UsageError(f"{setup}: {reason}") from None
    except package.PackageError as exc:
        raise UsageError(f"--policy: {exc}") from None
    except sandbox.SandboxError as exc:
        sys.stderr.write(exc.log)  # what the policy printed before it failed
        raise
    sys.stderr.write(df.attrs.get("log", ""))
    return df


def run_suite(args: argparse.Namespace) -> int:
    from wfbench.analysis.aggregate import AGGREGATE_NOTE, aggregate_cells, aggregate_suite
    from wfbench.analysis.tables import markdown_table, text_table
    from wfbench.core.seeds import describe
    from wfbench.harness.guard import PolicyLoadError
    from wfbench.harness.suite import evaluate_suite, suite_cells, suite_summary

    suite = check_suite_args(args)
    execution = check_backend_args(args, progress=not args.no_progress)
    out = check_writable(args.out, "--out") if args.out else None
    seeds = seed_list(args)
    try:
        df = evaluate_suite(args.policy, suite, seeds, split=args.split, act_timeout_s=args.act_timeout,
                            execution=execution)
    except PolicyLoadError as exc:
        raise UsageError(str(exc)) from None
    if out:
        df.to_csv(out, index=False)
    if args.format == "csv":
        df.to_csv(sys.stdout, index=False)
        return 0
    aggs = aggregate_suite({args.policy: df})
    if args.format == "json":
        print(json.dumps(suite_summary(df, seeds, aggs, policy=args.policy), indent=2, default=float))
        return 0
    table = markdown_table if args.format == "md" else text_table
    print(table(*suite_cells(df)))
    print(f"{suite.name} (hash {suite.hash}), seeds {describe(seeds)}: means over seeds; normalized = "
          "(NSW - random) / (bound - random), 0 the random policy, 1 the proven bound.\n")
    print(table(*aggregate_cells(aggs)))
    print(AGGREGATE_NOTE)
    return 0
