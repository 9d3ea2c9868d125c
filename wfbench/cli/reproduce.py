"""``wfbench reproduce``: regenerate the paper's Table 2, Table 3 or Figure 3, or the oracle gap (wfbench.reproduce)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from wfbench.cli.common import UsageError, add_backend_args, check_backend_args, positive, resolve_policy


def add_parser(sub) -> None:
    rp = sub.add_parser("reproduce", help="regenerate the paper's table2, table3 or figure3, or the oracle gap")
    rp.add_argument("target", help="table2, table3, figure3 or gap (heuristic, solver, oracle and the bound "
                    "per scenario)")
    rp.add_argument("--out", default="results", help="output folder (default: ./results)")
    rp.add_argument("--runs", type=positive, default=50, help="episodes per cell or row (default 50)")
    rp.add_argument("--methods", default=None, help="figure3 only: comma-separated policies to draw (default: "
                    "the paper's, solver, tuned, learned and oracle ones; the learned where their checkpoint and "
                    "torch are)")
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(rp)


def run(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    from wfbench.reproduce import TARGETS, target_size

    if args.target not in TARGETS:
        raise UsageError(f"unknown target {args.target!r}; allowed: {', '.join(TARGETS)}")
    check_backend_args(args)
    kwargs = {}
    if args.methods is not None:
        if args.target != "figure3":
            raise UsageError(f"--methods applies to figure3 only, not to {args.target}")
        kwargs["methods"] = tuple(dict.fromkeys(m.strip() for m in args.methods.split(",") if m.strip()))
        if not kwargs["methods"]:
            raise UsageError("--methods: give at least one policy name")
        for m in kwargs["methods"]:
            resolve_policy(m)  # an unknown name fails now, not after the others ran
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {args.out!r} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {args.out!r}: cannot create the folder: {exc.strerror or exc}") from None
    t0 = time.perf_counter()
    bar = None
    if not args.no_progress:
        bar = tqdm(total=target_size(args.target, **kwargs), desc=f"reproduce {args.target}", unit="run",
                   leave=False)

    def step(name: str) -> None:
        if bar:
            bar.set_postfix_str(name)
            bar.update(1)

    try:
        result = TARGETS[args.target](out, runs=args.runs, backend=args.backend, workers=args.workers,
                                      address=args.address, progress=step, **kwargs)
    finally:
        if bar:
            bar.close()
    print(result.text)
    print(f"\nwrote {', '.join(str(f) for f in result.files)} in {time.perf_counter() - t0:.1f} s")
    return 0
