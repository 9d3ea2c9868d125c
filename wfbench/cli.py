"""The ``wfbench`` command line.

User mistakes (unknown policy or scenario, bad numbers, unwritable output) print one
line saying what is wrong and what is allowed, and exit with status 2. A policy that
fails (raises, overruns its act timeout, returns a malformed action) prints one line
naming the policy, its file and line, and exits with status 1; ``--traceback`` prints
the whole trace first. ``module:attr`` policies are looked up in the current folder
first, as ``python -m`` does.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import sys
import time
from pathlib import Path

from tqdm.auto import tqdm

from leaderboard.reproduce import TARGETS, figure3_methods, table3_size
from leaderboard.store import Store, StoreError
from leaderboard.submit import SubmitError, seed_builtins, submit
from leaderboard.tracks import TRACKS, get_track
from policies import DECISIONS, get
from policies.registry import COMPOSITES, LEARNED, TUNED, learned_names
from wfbench.backends import check_backend
from wfbench.bench import run as run_bench
from wfbench.core.config import PRESETS, ScenarioConfig
from wfbench.core.seeds import SPEC_HELP as SEEDS_HELP
from wfbench.core.seeds import describe, resolve_seeds
from wfbench.evaluation import KPI_LABELS, KPIS, evaluate, format_kpi, summarize
from wfbench.guard import DEFAULT_ACT_TIMEOUT_S, PolicyError, PolicyLoadError
from wfbench.tables import markdown_table, text_table

EXIT_POLICY_FAILED = 1
EXIT_USAGE = 2


class UsageError(Exception):
    """A mistake in the command line: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, no usage dump
        raise UsageError(message)


def _int_at_least(lo: int):
    """An argparse type: an integer >= ``lo``, with a one-line message otherwise."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{v} is not allowed; allowed: an integer >= {lo}")
        return v

    return parse


_positive = _int_at_least(1)
_nonneg = _int_at_least(0)


def _seeds(text: str) -> str:
    """An argparse type: anything :func:`wfbench.core.seeds.resolve_seeds` takes, checked now."""
    try:
        resolve_seeds(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def seed_list(args: argparse.Namespace) -> list[int]:
    """The seeds of ``--seeds`` (a count starts at ``--seed-start``)."""
    if args.seeds.strip().isdigit():
        return list(range(args.seed_start, args.seed_start + int(args.seeds)))
    if args.seed_start:
        raise UsageError("--seed-start applies to a count of seeds only, not to a set, range or list")
    return resolve_seeds(args.seeds)


def add_backend_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--backend", default="process",
                   help="process (default: a pool over all cores), serial (this process) or ray")
    p.add_argument("--workers", type=_positive, default=None, help="processes or Ray tasks (default: all cores)")
    p.add_argument("--address", default=None, help="Ray cluster address for --backend ray (default: start a local one)")


def _act_timeout(text: str) -> float | None:
    """An argparse type: seconds > 0, or 0 for no limit."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; allowed: seconds > 0, or 0 for no limit")
    return v or None


def add_policy_run_args(p: argparse.ArgumentParser) -> None:
    """The options of commands that run a user's policy: its act timeout and --traceback."""
    p.add_argument("--act-timeout", type=_act_timeout, default=DEFAULT_ACT_TIMEOUT_S, metavar="SECONDS",
                   help=f"limit of each reset/act call of a module:attr policy (default {DEFAULT_ACT_TIMEOUT_S:g}; "
                        "0: none)")
    p.add_argument("--traceback", action="store_true", help="when the policy fails, print the whole trace")


def check_backend_args(args: argparse.Namespace) -> None:
    try:
        check_backend(args.backend, args.address)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="wfbench", description="A benchmark suite for service workforce optimization.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    e = sub.add_parser("evaluate", help="score a policy over seeds (Table 3 style row)")
    e.add_argument("--policy", required=True, help="registry name (see 'wfbench policies') or module:attr")
    e.add_argument("--scenario", default="paper-64", help="preset name or a .toml/.json config file")
    e.add_argument("--seeds", type=_seeds, default="50", help=f"{SEEDS_HELP} (default 50: the test set)")
    e.add_argument("--seed-start", type=_nonneg, default=0, help="first seed of a count (default 0)")
    add_backend_args(e)
    add_policy_run_args(e)
    e.add_argument("--format", default="table", choices=["table", "md", "csv", "json"], help="output format")
    e.add_argument("--out", default=None, help="also write the per-seed rows to this CSV file")
    e.add_argument("--no-progress", action="store_true", help="hide the progress bar")

    c = sub.add_parser("compare", help="several policies on the same seeds, paired differences to a baseline")
    c.add_argument("--policies", required=True, help="comma-separated registry names or module:attr entry points")
    c.add_argument("--baseline", default="heuristic", help="policy the paired differences are taken to")
    c.add_argument("--scenario", default="paper-64", help="preset name or a .toml/.json config file")
    c.add_argument("--seeds", type=_seeds, default="50", help=f"{SEEDS_HELP} (default 50: the test set)")
    c.add_argument("--seed-start", type=_nonneg, default=0, help="first seed of a count (default 0)")
    add_backend_args(c)
    add_policy_run_args(c)
    c.add_argument("--format", default="table", choices=["table", "md", "csv"], help="output format")
    c.add_argument("--plot", default=None, metavar="PATH", help="also draw the KPIs per policy and the paired "
                   "NSW differences with their intervals into this .png, .svg or .pdf file")
    c.add_argument("--no-progress", action="store_true", help="hide the progress bar")

    lb = sub.add_parser("leaderboard", help="submit policies to tracks and show the rankings")
    lsub = lb.add_subparsers(dest="lb_command", required=True, parser_class=_Parser)
    ls = lsub.add_parser("submit", help="evaluate a policy on a track's test seeds and store the results")
    ls.add_argument("--policy", required=True, help="registry name or module:attr entry point")
    ls.add_argument("--name", required=True, help="the entry's name on the leaderboard (resubmit it to resume)")
    ls.add_argument("--track", default="paper-64", help="track name (see 'wfbench leaderboard tracks')")
    ls.add_argument("--submitter", default=None, help="who submits (default: the user name)")
    ls.add_argument("--db", default=None, help="store file (default: $WFBENCH_DB or the user data folder)")
    ls.add_argument("--wall-time", type=float, default=3600.0, help="seconds before the evaluation is stopped")
    ls.add_argument("--memory", type=_positive, default=8192, help="memory limit of the evaluation in MiB")
    ls.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(ls)
    add_policy_run_args(ls)
    lw = lsub.add_parser("show", help="the ranking of a track")
    lw.add_argument("--track", default="paper-64")
    lw.add_argument("--format", default="table", help="table, md, csv or html")
    lw.add_argument("--out", default=None, help="write to this file instead of printing")
    lw.add_argument("--baseline", default="heuristic", help="entry the paired differences are taken to")
    lw.add_argument("--db", default=None, help="store file (default: $WFBENCH_DB or the user data folder)")
    ld = lsub.add_parser("seed", help="fill in the built-in entries (random, heuristic, solver, ...)")
    ld.add_argument("--track", default=None, help="one track (default: all)")
    ld.add_argument("--db", default=None)
    ld.add_argument("--no-progress", action="store_true")
    add_backend_args(ld)
    lsub.add_parser("tracks", help="list the tracks with their hashes and seeds")

    rp = sub.add_parser("reproduce", help="regenerate the paper's table2, table3 or figure3, or the oracle gap")
    rp.add_argument("target", help="table2, table3, figure3 or gap (heuristic, solver, oracle and the bound "
                    "per scenario)")
    rp.add_argument("--out", default="results", help="output folder (default: ./results)")
    rp.add_argument("--runs", type=_positive, default=50, help="episodes per cell or row (default 50)")
    rp.add_argument("--methods", default=None, help="figure3 only: comma-separated policies to draw (default: "
                    "the paper's, solver, tuned, learned and oracle ones; the learned where their checkpoint and "
                    "torch are)")
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(rp)

    t = sub.add_parser("tune", help="search a policy's tunable parameters on public seeds (Optuna TPE) and write "
                       "a tuned-policy file")
    t.add_argument("policy", help="registry name or D+W+P composite whose parts declare parameters (heuristic, "
                   "solver, ...)")
    t.add_argument("--scenario", default="paper-64", help="preset name or a .toml/.json config file")
    t.add_argument("--trials", type=_positive, default=100,
                   help="the study's total of finished trials (default 100); re-run the same command to resume, "
                        "raise it to extend")
    t.add_argument("--seeds", type=_seeds, default="public",
                   help="tuning seeds: public (default, 1000-1049), public:N or train:N; test seeds are refused")
    t.add_argument("--params", default=None,
                   help="comma-separated parameters to search, each optionally narrowed as name=low:high "
                        "(default: all the policy declares; --list shows them)")
    t.add_argument("--list", action="store_true", help="list the policy's tunable parameters and ranges, and exit")
    t.add_argument("--study-db", default="wfbench-tune.db", help="SQLite file of the study (default "
                   "./wfbench-tune.db)")
    t.add_argument("--study-name", default=None, help="the study's name in it (default POLICY@SCENARIO)")
    t.add_argument("--sampler-seed", type=_nonneg, default=0, help="seed of the TPE sampler (default 0)")
    t.add_argument("--name", default=None, help="the tuned policy's name (default POLICY-tuned)")
    t.add_argument("--out", default=None, help="tuned-policy file, .json or .toml (default "
                   "./tuned-POLICY-SCENARIO.json)")
    t.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(t)

    s = sub.add_parser("scenarios", help="list the presets, or show one as TOML")
    s.add_argument("name", nargs="?", help="a preset to show")

    sub.add_parser("policies", help="list the registered policies")

    m = sub.add_parser("simulate", help="run one episode, optionally render it to a GIF")
    m.add_argument("--scenario", default="paper-64")
    m.add_argument("--seed", type=_nonneg, default=0)
    m.add_argument("--policy", default="heuristic")
    m.add_argument("--render", default=None, help="write an animated GIF here")
    m.add_argument("--every", type=_positive, default=4, help="one frame every this many steps (default 4)")
    m.add_argument("--steps", type=_positive, default=None, help="stop after this many steps")
    m.add_argument("--no-progress", action="store_true", help="hide the progress bar")

    b = sub.add_parser("bench", help="measure env-steps per second")
    b.add_argument("--scenario", default="paper-64")
    b.add_argument("--quick", action="store_true", help="fewer and smaller measurements")
    b.add_argument("--json", default=None, help="also write the results to this JSON file")
    b.add_argument("--rounds", type=_positive, default=None,
                   help="measure every row this many times, interleaved (default 3; 1 with --quick)")

    tr = sub.add_parser("train", help="train a policy with PPO (docs/rl.md); needs torch (the rl extra)")
    tr.add_argument("--algo", default=None, choices=["ppo", "impala", "hindsight"],
                    help="ppo (default), impala (actor-learner, V-trace) or hindsight (imitation of the hindsight "
                         "oracles, DAgger); docs/rl.md, docs/impala.md, docs/hindsight-learning.md")
    tr.add_argument("--variant", default=None, choices=["joint", "dispatch"],
                    help="joint: all three decisions; dispatch: the dispatch head only, heuristic workforce and "
                         "positioning (default joint)")
    tr.add_argument("--scenario", default=None, help="scenario to train on (default paper-64)")
    tr.add_argument("--steps", type=_positive, default=None, help="environment steps in all (default 1000000)")
    tr.add_argument("--model", default=None,
                    help="network size: cpu (no attention, fastest on CPU), tiny, small or paper (~0.5M parameters)")
    tr.add_argument("--num-envs", type=_positive, default=None, help="environments side by side (default 32)")
    tr.add_argument("--num-steps", type=_positive, default=None, help="steps per rollout (default 32)")
    tr.add_argument("--epochs", type=_positive, default=None, help="PPO epochs per rollout (default 2)")
    tr.add_argument("--minibatches", type=_positive, default=None, help="minibatches of whole sequences (default 2)")
    tr.add_argument("--lr", type=float, default=None, help="Adam learning rate (default 3e-4)")
    tr.add_argument("--ent-coef", type=float, default=None, help="entropy bonus (default 0.003)")
    tr.add_argument("--seed", type=_nonneg, default=None, help="run seed: network init, sampling, training seeds")
    tr.add_argument("--device", default=None, choices=["auto", "cpu", "cuda"], help="default auto")
    tr.add_argument("--compile", action="store_true", help="torch.compile the network (CUDA)")
    tr.add_argument("--no-bf16", action="store_true", help="no bf16 autocast on CUDA")
    tr.add_argument("--threads", type=_positive, default=None, help="torch CPU threads (default 1)")
    tr.add_argument("--checkpoint-every", type=_positive, default=None, help="updates between checkpoints (20)")
    tr.add_argument("--eval-every", type=_nonneg, default=None,
                    help="updates between scores on the public seeds that pick best.pt (default 20; 0: never)")
    tr.add_argument("--eval-seeds", type=_seeds, default=None,
                    help="public seeds that select the checkpoint (default public:10; test seeds are refused)")
    tr.add_argument("--run-dir", default=None, help="folder of the run (default runs/ppo-VARIANT-SCENARIO)")
    tr.add_argument("--init", default=None, metavar="CKPT",
                    help="start from the network weights of a checkpoint (a new run: fresh optimizer and counters)")
    tr.add_argument("--gae-lambda", type=float, default=None, help="GAE lambda (default 0.95)")
    tr.add_argument("--gamma", type=float, default=None, help="discount (default 0.995)")
    tr.add_argument("--agents", default=None, choices=["joint", "independent"],
                    help="ppo: one network for the three decisions (joint, default) or one network per decision, "
                         "each with its own critic, trained together (independent); docs/rl.md")
    tr.add_argument("--address", default=None, metavar="ADDR",
                    help="impala: run the actors on a Ray cluster ('auto', 'ray://host:10001' or 'local' for a "
                         "Ray instance on this machine); docs/impala.md")
    tr.add_argument("--resume", default=None, metavar="CKPT",
                    help="continue a run from its checkpoint (latest.pt); its settings are kept, --steps may raise "
                         "the total")
    tr.add_argument("--set", action="append", metavar="KEY=VALUE",
                    help="any other setting of the algorithm's config (repeatable), e.g. --set rho_bar=0.9")
    tr.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    tr.add_argument("--no-tensorboard", action="store_true", help="write no TensorBoard logs")
    return p


def _resolve_scenario(name: str):
    try:
        return ScenarioConfig.resolve(name)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _resolve_policy(spec: str):
    try:
        return get(spec)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _check_writable(path: str, what: str) -> Path:
    out = Path(path)
    if not out.parent.exists() or not out.parent.is_dir():
        raise UsageError(f"{what} {path!r}: folder {str(out.parent)!r} does not exist")
    return out


def cmd_evaluate(args: argparse.Namespace) -> int:
    config = _resolve_scenario(args.scenario)
    check_backend_args(args)
    out = _check_writable(args.out, "--out") if args.out else None
    seeds = seed_list(args)
    try:  # evaluate loads the policy once; a spec that names none is a usage error
        df = evaluate(args.policy, config, seeds, backend=args.backend, workers=args.workers, address=args.address,
                      progress=not args.no_progress, act_timeout_s=args.act_timeout)
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
        header = ["Policy", *[KPI_LABELS[k] for k in KPIS]]
        rows = [[args.policy, *[format_kpi(*summary[k]) for k in KPIS]]]
        print((markdown_table if args.format == "md" else text_table)(header, rows))
        print(f"{config.name}, seeds {describe(seeds)}: mean (25%-75%) over seeds of the "
              "episode means; NSW higher is better.")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    # imported here, not at the top: wfbench.compare loads scipy.stats (wfbench.stats), which
    # took the warm start of 'wfbench evaluate --seeds 1' from 1.8 to 2.7 s of CPU (/usr/bin/time)
    from wfbench.compare import compare, format_comparison, plot_comparison
    from wfbench.plots import figure_format

    config = _resolve_scenario(args.scenario)
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
        plot = _check_writable(args.plot, "--plot")
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


def cmd_leaderboard(args: argparse.Namespace) -> int:
    # imported here for the same reason as in cmd_compare: the report loads scipy.stats
    from leaderboard.report import FORMATS, ranking, render

    def track(name: str):
        try:
            return get_track(name)
        except ValueError as exc:
            raise UsageError(str(exc)) from None

    try:
        if args.lb_command == "tracks":
            for t in TRACKS.values():
                print(f"{t.name:<14s} hash {t.hash}  test seeds {t.test_seeds[0]}..{t.test_seeds[-1]}  "
                      f"public seeds {t.public_seeds[0]}..{t.public_seeds[-1]}  {t.description}")
            return 0
        if args.lb_command == "submit":
            tr = track(args.track)
            check_backend_args(args)
            out = submit(tr, args.policy, args.name, submitter=args.submitter, db=args.db, backend=args.backend,
                         workers=args.workers, address=args.address, wall_time_s=args.wall_time,
                         memory_mb=args.memory, progress=not args.no_progress, act_timeout_s=args.act_timeout)
            store = Store(args.db)
            if out.status == "complete":
                print(f"{args.name} on {tr.name}: complete, {out.stored_rows} seeds stored ({out.new_rows} new) "
                      f"in {store.path}, {out.seconds:.1f} s")
                return 0
            if args.traceback and out.trace:
                print(out.trace, end="" if out.trace.endswith("\n") else "\n", file=sys.stderr)
            print(f"wfbench: submission {args.name!r} on {tr.name} failed: {out.reason} "
                  f"({out.stored_rows} seeds kept in {store.path}; fix the policy and submit again to resume"
                  f"{'' if args.traceback or not out.trace else '; --traceback prints the whole trace'})",
                  file=sys.stderr)
            return EXIT_POLICY_FAILED
        if args.lb_command == "seed":
            check_backend_args(args)
            tracks = [track(args.track)] if args.track else list(TRACKS.values())
            failed = 0
            for tr in tracks:
                for out in seed_builtins(tr, db=args.db, backend=args.backend, workers=args.workers,
                                         address=args.address, progress=not args.no_progress):
                    print(f"{tr.name:<14s} {out.submission.name:<20s} {out.status} ({out.stored_rows} seeds, "
                          f"{out.new_rows} new, {out.seconds:.1f} s){': ' + out.reason if out.reason else ''}")
                    failed += out.status != "complete"
            return 1 if failed else 0
        # show
        tr = track(args.track)
        if args.format not in FORMATS:
            raise UsageError(f"--format {args.format!r} is not allowed; allowed: {', '.join(FORMATS)}")
        out_path = _check_writable(args.out, "--out") if args.out else None
        r = ranking(Store(args.db, create=False), tr, baseline=args.baseline)  # showing never creates a store
        for msg in r.refused:
            print(f"wfbench: warning: {msg}", file=sys.stderr)
        text = render(r, args.format)
        if out_path:
            try:
                out_path.write_text(text)
            except OSError as exc:
                raise UsageError(f"cannot write {out_path}: {exc.strerror or exc}") from None
            print(f"wrote {out_path}")
        else:
            print(text, end="" if text.endswith("\n") else "\n")
        return 0
    except (StoreError, SubmitError) as exc:
        raise UsageError(str(exc)) from None


def cmd_reproduce(args: argparse.Namespace) -> int:
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
            _resolve_policy(m)  # an unknown name fails now, not after the others ran
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
        sizes = {"table2": lambda: 20, "table3": table3_size, "gap": lambda: 12,
                 "figure3": lambda: len(kwargs.get("methods", figure3_methods()))}
        bar = tqdm(total=sizes[args.target](), desc=f"reproduce {args.target}", unit="run", leave=False)

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


def cmd_tune(args: argparse.Namespace) -> int:
    from wfbench.tune import check_tuning_seeds, search_space, tune

    policy = _resolve_policy(args.policy)
    if args.list:
        try:
            space = search_space(policy)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        current = policy.params()
        for key, p in space.items():
            print(f"{key:<30s} {p.describe():<36s} now {current[key]:g}")
        return 0
    config = _resolve_scenario(args.scenario)
    check_backend_args(args)
    try:
        seeds = check_tuning_seeds(args.seeds)
    except ValueError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    out = args.out or f"tuned-{args.policy}-{config.name}.json"
    _check_writable(out, "--out")
    _check_writable(args.study_db, "--study-db")
    command = "wfbench " + shlex.join(args.argv)
    try:
        r = tune(args.policy, args.scenario, args.trials, seeds=seeds, params=args.params, study_db=args.study_db,
                 study_name=args.study_name, backend=args.backend, workers=args.workers, address=args.address,
                 sampler_seed=args.sampler_seed, out=out, name=args.name, progress=not args.no_progress,
                 command=command)
    except KeyboardInterrupt:
        print(f"wfbench: interrupted; the finished trials are kept in {args.study_db} (study "
              f"{args.study_name or args.policy + '@' + args.scenario!r}): run the same command again to resume",
              file=sys.stderr)
        return 130
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    t = r.tuned
    untuned = f", untuned {r.untuned_score:.4f}" if r.untuned_score is not None else ""
    print(f"{t.name}: best mean NSW {t.best_score:.4f}{untuned} on {config.name} seeds {t.seed_set}, "
          f"{t.trials} trials ({r.new_trials} new) in {r.study_db} study {r.study_name!r}")
    for k, v in t.params.items():
        print(f"  {k} = {v:g}")
    print(f"wrote {r.path}; judge it on the test seeds: wfbench compare --policies {args.policy},{r.path} "
          f"--scenario {args.scenario} --seeds test")
    return 0


def cmd_scenarios(args: argparse.Namespace) -> int:
    if args.name:
        print(_resolve_scenario(args.name).to_toml(), end="")
        return 0
    print(f"{'name':<24s} {'grid':>9s} {'facilities':>12s} {'personnel':>11s} {'horizon':>8s}")
    for name, c in PRESETS.items():
        print(f"{name:<24s} {c.grid_width:>4d}x{c.grid_height:<4d} {c.initial_facilities:>5d}/{c.max_facilities:<6d}"
              f" {c.initial_personnel:>4d}/{c.max_personnel:<6d} {c.horizon:>8d}")
    return 0


def cmd_policies(args: argparse.Namespace) -> int:
    for name, (d, w, p, text) in COMPOSITES.items():
        print(f"{name:<22s} dispatch={d}, workforce={w}, positioning={p}: {text}")
    for name, (file, text) in TUNED.items():
        print(f"{name:<22s} policies/tuned/{file}: {text}")
    for name in learned_names():
        print(f"{name:<22s} policies/neural/checkpoints/{LEARNED[name][0]}: {LEARNED[name][1]}")
    for decision, table in DECISIONS.items():
        print(f"{decision} decisions (for Composite and fixed agents): {', '.join(table)}")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from wfbench.core.simulator import Simulator
    from wfbench.envs.render import Renderer, save_gif

    config = _resolve_scenario(args.scenario)
    policy = _resolve_policy(args.policy)
    out = _check_writable(args.render, "--render") if args.render else None
    sim = Simulator(config, [args.seed])
    obs = sim.reset()
    policy.reset([args.seed])
    renderer = Renderer(config) if out else None  # one figure for every frame (wfbench/envs/render.py)
    frames = [renderer.frame(sim)] if renderer else []
    limit = min(args.steps or config.horizon, config.horizon)
    with tqdm(total=limit, desc=f"simulate {config.name} seed {args.seed}", unit="step", leave=False,
              disable=args.no_progress) as bar:
        while not sim.done and sim.t < limit:
            sim.step(policy.act(obs))
            obs = sim.observe()
            if renderer and sim.t % args.every == 0:
                frames.append(renderer.frame(sim))
                bar.set_postfix(frames=len(frames), refresh=False)
            bar.update(1)
    means = sim.episode_means()
    print(f"{config.name} seed {args.seed}, {args.policy}, {sim.t} steps: "
          + ", ".join(f"{k}={means[k][0]:.4g}" for k in ("workforce_cost", "utilization", "downtime", "nsw")))
    if out:
        save_gif(frames, out)
        print(f"wrote {len(frames)} frames to {out}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    _resolve_scenario(args.scenario)
    if args.json:
        _check_writable(args.json, "--json")
    run_bench(args.scenario, quick=args.quick, json_path=args.json, rounds=args.rounds)
    return 0


_TRAIN_FLAGS = {"variant": "variant", "scenario": "scenario", "steps": "steps", "model": "model",
                "num_envs": "num_envs", "num_steps": "num_steps", "epochs": "epochs", "minibatches": "minibatches",
                "lr": "lr", "ent_coef": "ent_coef", "seed": "seed", "device": "device", "threads": "threads",
                "checkpoint_every": "checkpoint_every", "eval_every": "eval_every", "eval_seeds": "eval_seeds",
                "run_dir": "run_dir", "init": "init", "gae_lambda": "gae_lambda", "gamma": "gamma",
                "agents": "agents", "address": "address"}


# --algo -> (module under wfbench.train, its config class); each module has a Trainer(config, resume, ...)
_TRAIN_ALGOS = {"ppo": ("ppo", "TrainConfig"), "impala": ("impala", "ImpalaConfig"),
                "hindsight": ("hindsight", "HindsightConfig")}


def _train_settings(config_cls, given: dict, algo: str, pairs: list[str]) -> dict:
    """The flags given plus ``--set KEY=VALUE`` pairs, checked against the algorithm's config fields."""
    import dataclasses
    import json

    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    for name in given:
        if name not in fields:
            raise ValueError(f"--{name.replace('_', '-')} does not apply to --algo {algo}; its settings: "
                             f"{', '.join(fields)} (set any of them with --set KEY=VALUE)")
    out = dict(given)
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or key not in fields:
            raise ValueError(f"--set {pair!r}: expected KEY=VALUE with KEY one of the --algo {algo} settings: "
                             f"{', '.join(fields)}")
        default = fields[key].default if fields[key].default is not dataclasses.MISSING else None
        try:
            if isinstance(default, bool):
                if text.lower() not in ("true", "false", "1", "0"):
                    raise ValueError
                value = text.lower() in ("true", "1")
            elif isinstance(default, int | float) and not isinstance(default, bool):
                value = type(default)(text)
            elif isinstance(default, str):
                value = text
            else:
                value = json.loads(text)
        except ValueError:
            kind = type(default).__name__ if default is not None else "JSON"
            raise ValueError(f"--set {pair!r}: {key} takes a {kind} value (its default: {default!r})") from None
        out[key] = value
    return out


def cmd_train(args: argparse.Namespace) -> int:
    import importlib

    try:  # torch is needed here only: the rest of the command line works without it
        import torch  # noqa: F401
    except ImportError as exc:
        raise UsageError(f"wfbench train needs torch ({exc}); install the rl extra: "
                         "pip install 'wfbench[rl]'") from None
    from policies.neural.policy import load_checkpoint

    given = {field: getattr(args, flag) for flag, field in _TRAIN_FLAGS.items() if getattr(args, flag) is not None}
    if args.compile:
        given["compile"] = True
    if args.no_bf16:
        given["bf16"] = False
    try:
        saved = None
        if args.resume:
            saved = load_checkpoint(args.resume)
            if "optimizer" not in saved:
                raise ValueError(f"checkpoint {args.resume!r} has no optimizer state (a best.pt?): resume from "
                                 "latest.pt or a checkpoints/update_*.pt")
            run_algo = saved.get("algo", "ppo")
            if args.algo is not None and args.algo != run_algo:
                raise ValueError(f"checkpoint {args.resume!r} is a {run_algo} run, not --algo {args.algo}")
        algo = saved.get("algo", "ppo") if saved is not None else (args.algo or "ppo")
        module_name, cls_name = _TRAIN_ALGOS[algo]
        module = importlib.import_module(f"wfbench.train.{module_name}")
        config_cls = getattr(module, cls_name)
        given = _train_settings(config_cls, given, algo, args.set or [])
        if saved is not None:
            changed = sorted(k for k in given if k not in ("steps", "run_dir", "device", "threads", "address")
                             and given[k] != saved["train_config"].get(k))
            if changed:
                raise ValueError(f"--resume keeps the run's settings; these differ from it: {', '.join(changed)}")
            config = config_cls.from_dict({**saved["train_config"], **given})
        else:
            given.setdefault("run_dir", str(Path("runs") / f"{algo}-{given.get('variant', 'joint')}-"
                                                            f"{given.get('scenario', 'paper-64')}"))
            config = config_cls(**given)
        trainer = module.Trainer(config, resume=args.resume, progress=not args.no_progress,
                                 log=not args.no_tensorboard)
    except (ValueError, TypeError) as exc:
        raise UsageError(str(exc)) from None
    trainer.train()
    best = trainer.best
    print(f"trained {trainer.global_step} environment steps ({algo}) in {config.run_dir}")
    if best["update"] is not None:
        print(f"best.pt: update {best['update']}, mean NSW {best['score']:.4f} on public seeds "
              f"{best['seeds'][0]}-{best['seeds'][-1]} ({best['mode']}); evaluate with "
              f"wfbench evaluate --policy ppo:{Path(config.run_dir) / 'best.pt'}")
    print(f"latest.pt: {Path(config.run_dir) / 'latest.pt'}")
    return 0


COMMANDS = {"evaluate": cmd_evaluate, "compare": cmd_compare, "leaderboard": cmd_leaderboard,
            "reproduce": cmd_reproduce, "tune": cmd_tune, "scenarios": cmd_scenarios, "policies": cmd_policies,
            "simulate": cmd_simulate, "bench": cmd_bench, "train": cmd_train}


def _search_current_folder() -> None:
    """Put the current folder first on ``sys.path``, as ``python -m`` does.

    The ``wfbench`` script's own folder is what Python puts there, so without this a
    ``--policy mypkg.mod:MyPolicy`` next to the user would not be found. The absolute
    path: worker processes inherit ``sys.path`` and may start elsewhere.
    """
    cwd = os.getcwd()
    if cwd not in sys.path:
        sys.path.insert(0, cwd)


def main(argv: list[str] | None = None) -> int:
    args = None
    try:
        _search_current_folder()
        args = build_parser().parse_args(argv)
        args.argv = list(sys.argv[1:] if argv is None else argv)  # recorded by commands that write provenance
        return COMMANDS[args.command](args)
    except UsageError as exc:
        print(f"wfbench: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except PolicyError as exc:
        if getattr(args, "traceback", False):
            print(exc.trace or "(no trace)", end="" if exc.trace.endswith("\n") else "\n", file=sys.stderr)
            hint = ""
        else:
            hint = " (--traceback prints the whole trace)"
        print(f"wfbench: error: {exc}{hint}", file=sys.stderr)
        return EXIT_POLICY_FAILED
    except KeyboardInterrupt:
        print("wfbench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
