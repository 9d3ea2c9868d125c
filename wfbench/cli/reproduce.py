"""``wfbench reproduce``: regenerate the paper's Table 2, Table 3 or Figure 3, the oracle gap, or the suite.

The targets are in :mod:`wfbench.reproduce`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from wfbench.cli.common import (
    UsageError,
    add_backend_args,
    check_backend_args,
    positive,
    resolve_policy,
    seeds_spec,
)


def add_parser(sub) -> None:
    rp = sub.add_parser("reproduce", help="regenerate the paper's table2, table3 or figure3, the oracle gap, the "
                        "suite, its verify (bit for bit) or the frontier (held-out score against compute)")
    rp.add_argument("target", help="table2, table3, figure3, gap (heuristic, solver, oracle and the bound "
                    "per scenario), suite (every built-in policy on every scenario of suite-v1, normalized and "
                    "aggregated; docs/suite.md), verify (recompute the pieces of the suite run in --out and "
                    "compare them bit for bit; exit 1 if one differs) or frontier (held-out IQM against decision "
                    "cost per policy, and the verdict per budget; docs/suite.md)")
    rp.add_argument("--out", default="results", help="output folder (default: ./results)")
    rp.add_argument("--runs", type=positive, default=None, help="episodes per cell or row (default 50); verify: "
                    "the first seeds of each piece to recompute (default 1)")
    rp.add_argument("--methods", default=None, help="figure3 only: comma-separated policies to draw (default: "
                    "the paper's, solver, tuned, learned and oracle ones; the learned where their checkpoint and "
                    "torch are)")
    rp.add_argument("--seeds", type=seeds_spec, default=None, help="suite, verify and frontier only: the seeds "
                    "(suite default: test, 0-49, instead of --runs; frontier: the committed frontier's; verify "
                    "default: each piece's first --runs seeds, see --runs)")
    rp.add_argument("--policies", default=None, help="suite, verify and frontier only: comma-separated "
                    "policies (default: every built-in policy, the shipped networks, five lookaheads and the oracle; "
                    "frontier: the committed frontier's)")
    rp.add_argument("--scenarios", default=None, help="suite, verify and frontier only: comma-separated "
                    "scenario ids or presets of the suite (default: all; frontier: the committed frontier's, else the "
                    "split's)")
    rp.add_argument("--split", default=None, choices=["train", "heldout"], help="frontier only: the split "
                    "(default heldout)")
    rp.add_argument("--reuse", default=None, help="suite and frontier only: comma-separated suite run folders "
                    "whose cached pieces are read, in order, after --out's and before anything is played (suite "
                    "default: none; frontier default: the checkout's docs/results/frontier-v1, "
                    "docs/results/suite-v1-50 and docs/results/reference-v2, the committed runs, wherever the "
                    "command runs from)")
    rp.add_argument("--classes", default=None, metavar="FILE", help="frontier only: also write each policy's CPU ms "
                    "per env-step to FILE, the budget classes wfbench policies prints (the committed frontier's: "
                    "policies/budgets.json, held-out split only)")
    rp.add_argument("--plan", action="store_true", help="suite and frontier only: print what would be played "
                    "(the pieces no stored run holds) and its estimated CPU time, and play nothing")
    rp.add_argument("--no-networks", action="store_true", help="suite only: leave the shipped networks out")
    rp.add_argument("--no-members", action="store_true", help="suite only: play a learned method's shipped pick "
                    "only, not its training seeds (#seedK; the suite's per-seed table is then left out)")
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(rp)


def run(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    from wfbench.reproduce import check_target, output_folder, parse_methods, reproduce, target_size

    try:
        check_target(args.target)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    execution = check_backend_args(args)
    kwargs = {}
    try:
        methods = parse_methods(args.methods, args.target, "--methods")
        if methods is not None:
            kwargs["methods"] = methods
        kwargs.update(_suite_kwargs(args))
        out = output_folder(args.out, "--out")  # reproduce() checks it too; made here, before the progress bar
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    t0 = time.perf_counter()
    bar = None
    if not args.no_progress:
        bar = tqdm(total=target_size(args.target, **kwargs), desc=f"reproduce {args.target}", unit="run",
                   leave=False)

    def step(name: str) -> None:
        if bar is not None:
            bar.set_postfix_str(name)
            bar.update(1)

    try:
        # the frontier's defaults are the committed frontier's seeds (wfbench.reproduce.frontier.committed_settings)
        runs = args.runs if args.runs is not None else (1 if args.target == "verify" else
                                                        None if args.target == "frontier" else 50)
        result = reproduce(args.target, out, runs=runs, execution=execution, progress=step, **kwargs)
    finally:
        if bar is not None:
            bar.close()
    print(result.text)
    if kwargs.get("plan_only"):
        return 0
    if args.target == "verify":
        return 1 if any(v.differences for v in result.verdicts) else 0
    print(f"\nwrote {', '.join(str(f) for f in result.files)} in {time.perf_counter() - t0:.1f} s")
    return 0


def _names(text: str, option: str) -> tuple[str, ...]:
    names = tuple(dict.fromkeys(x.strip() for x in text.split(",") if x.strip()))
    if not names:
        raise UsageError(f"{option}: give at least one name")
    return names


def _suite_kwargs(args: argparse.Namespace) -> dict:
    """The suite target's options, checked now (an unknown policy or scenario fails before anything runs)."""
    given = [o for o, v in (("--seeds", args.seeds), ("--policies", args.policies), ("--scenarios", args.scenarios))
             if v is not None]
    own = [o for o, v in (("--split", args.split), ("--classes", args.classes)) if v is not None]
    for option, on in (("--no-networks", args.no_networks), ("--no-members", args.no_members)):
        if on and args.target != "suite":
            hint = " (give --policies)" if args.target in ("frontier", "verify") else ""
            raise UsageError(f"{option} applies to suite only, not to {args.target}{hint}")
    if args.plan and args.target not in ("suite", "frontier"):
        raise UsageError(f"--plan applies to suite and frontier only, not to {args.target}")
    if args.reuse is not None and args.target not in ("suite", "frontier"):
        raise UsageError(f"--reuse applies to suite and frontier only, not to {args.target}")
    if own and args.target != "frontier":
        raise UsageError(f"{own[0]} applies to frontier only, not to {args.target}")
    if args.target not in ("suite", "verify", "frontier"):
        if given:
            raise UsageError(f"{given[0]} applies to suite, verify and frontier only, not to {args.target}")
        return {}
    from wfbench.scenarios import get_suite

    kwargs: dict = {"networks": not args.no_networks, "members": not args.no_members} \
        if args.target == "suite" else {}
    if args.target in ("suite", "frontier"):
        kwargs["plan_only"] = args.plan  # the plan is the output; otherwise it is said first, on stderr
        if not args.plan:
            kwargs["announce"] = lambda text: print(text, file=sys.stderr, flush=True)
    if args.split is not None:
        kwargs["split"] = args.split
    if args.reuse is not None:
        kwargs["reuse"] = _names(args.reuse, "--reuse")
        for folder in kwargs["reuse"]:
            if not (Path(folder) / "cache").is_dir():
                raise UsageError(f"--reuse: {folder} holds no cache/ folder; allowed: the --out folders of "
                                 "wfbench reproduce suite or frontier runs (e.g. docs/results/suite-v1-50)")
    if args.classes is not None:
        if (args.split or "heldout") != "heldout":
            raise UsageError(f"--classes applies to the held-out split only (the verdict's), not to {args.split}")
        kwargs["classes"] = Path(args.classes)
    if args.seeds is not None:
        kwargs["seeds"] = args.seeds
    if args.policies is not None:
        kwargs["policies"] = _names(args.policies, "--policies")
        for p in kwargs["policies"]:
            if not (args.target == "verify" and p == "bound"):  # verify's pieces include the bound's
                resolve_policy(p)
    if args.scenarios is not None:
        kwargs["scenarios"] = _names(args.scenarios, "--scenarios")
        suite = get_suite("suite-v1")
        for x in kwargs["scenarios"]:
            try:
                suite.scenario(x)
            except ValueError as exc:
                raise UsageError(f"--scenarios: {exc}") from None
        if args.target == "frontier":
            from wfbench.reproduce.frontier import _chosen

            try:
                _chosen(suite, kwargs["scenarios"], kwargs.get("split", "heldout"))
            except ValueError as exc:
                raise UsageError(f"--scenarios: {exc}") from None
    return kwargs
