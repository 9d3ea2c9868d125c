"""``wfbench leaderboard``: submit policies to tracks, seed the built-in entries, withdraw one, show the rankings.

``upload`` sends a policy package to a hosted board (``wfbench serve``) instead, where it is
evaluated in a sandbox (:mod:`wfbench.leaderboard.server.client`).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

from wfbench.cli.common import (
    EXIT_POLICY_FAILED,
    Parser,
    UsageError,
    add_backend_args,
    add_policy_run_args,
    check_backend_args,
    check_writable,
    positive,
)

TOKEN_ENV = "WFBENCH_TOKEN"  # where 'upload' reads the token when --token is not given (a command line is visible)


def budget_limit(text: str) -> float:
    """An argparse type: a finite number > 0 (a budget in milliseconds or seconds)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; allowed: a number > 0")
    return v


def add_parser(sub) -> None:
    lb = sub.add_parser("leaderboard", help="submit policies to tracks and show the rankings")
    lsub = lb.add_subparsers(dest="lb_command", required=True, parser_class=Parser)
    ls = lsub.add_parser("submit", help="evaluate a policy on a track's test seeds and store the results")
    ls.add_argument("--policy", required=True, help="registry name or module:attr entry point")
    ls.add_argument("--name", required=True, help="the entry's name on the leaderboard (resubmit it to resume)")
    ls.add_argument("--track", default="paper-64", help="track name (see 'wfbench leaderboard tracks')")
    ls.add_argument("--submitter", default=None, help="who submits (default: the user name)")
    ls.add_argument("--db", default=None, help="store file (default: $WFBENCH_DB or the user data folder)")
    ls.add_argument("--wall-time", type=float, default=3600.0, help="seconds before the evaluation is stopped")
    ls.add_argument("--memory", type=positive, default=8192, help="memory limit of the evaluation in MiB")
    ls.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ls.add_argument("--replace", action="store_true",
                    help="the name is taken: move its entry to the store's audit tables and evaluate every seed anew")
    add_backend_args(ls)
    add_policy_run_args(ls)
    lw = lsub.add_parser("show", help="the ranking of a track")
    lw.add_argument("--track", default="paper-64")
    lw.add_argument("--format", default="table", help="table, md, csv or html")
    lw.add_argument("--out", default=None, help="write to this file instead of printing")
    lw.add_argument("--baseline", default="heuristic", help="entry the paired differences are taken to")
    lw.add_argument("--db", default=None, help="store file (default: $WFBENCH_DB or the user data folder)")
    lw.add_argument("--max-decision-ms", type=budget_limit, default=None,
                    help="rank only entries whose p99 wall time per decision is at most this many milliseconds")
    lw.add_argument("--max-cpu-s", type=budget_limit, default=None,
                    help="rank only entries that used at most this many CPU seconds per episode")
    ld = lsub.add_parser("baselines", help="fill in the built-in entries (random, heuristic, solver, ...)")
    ld.add_argument("--track", default=None, help="one track (default: every track but one that runs a whole "
                                                  "suite, such as suite-v1: that one only when named)")
    ld.add_argument("--db", default=None)
    ld.add_argument("--no-progress", action="store_true")
    add_backend_args(ld)
    lsub.add_parser("tracks", help="list the tracks with their hashes and seeds")
    lx = lsub.add_parser("withdraw", help="take an entry off a track's board (its rows go to the audit tables); "
                                          "with --server, your submission ID off a hosted board")
    lx.add_argument("--name", default=None, help="the entry's name (the local store)")
    lx.add_argument("--server", default=None, help="a hosted board's URL: withdraw your submission --id there")
    lx.add_argument("--id", type=int, default=None, help="the hosted submission's id (see 'wfbench leaderboard mine')")
    lx.add_argument("--token", default=None, help=f"your account's token on the hosted board (default: ${TOKEN_ENV})")
    lx.add_argument("--track", default="paper-64")
    lx.add_argument("--reason", default="", help="why, kept in the audit tables")
    lx.add_argument("--db", default=None, help="store file (default: $WFBENCH_DB or the user data folder)")
    lu = lsub.add_parser("upload", help="upload a policy package to a hosted board and follow its evaluation")
    lu.add_argument("--server", required=True, help="the hosted board's URL, e.g. http://127.0.0.1:8000")
    lu.add_argument("--token", default=None, help=f"your account's token (default: ${TOKEN_ENV})")
    lu.add_argument("--policy", required=True,
                    help="a module:attr entry point (packed from the current folder), a folder with "
                         "wfbench-policy.json, or a .zip/.whl policy package")
    lu.add_argument("--track", default="paper-64", help="track name (see 'wfbench leaderboard tracks')")
    lu.add_argument("--phase", default="dev", help="dev (the public seeds, log shown) or test (hidden seeds, "
                                                   "aggregate only, quota per account)")
    lu.add_argument("--name", default=None, help="the entry's name on the board (default: the entry point)")
    lu.add_argument("--entry", default=None, help="the entry point in the package (default: the manifest's)")
    lu.add_argument("--no-wait", action="store_true", help="print the submission's page and return at once")
    lu.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    lm = lsub.add_parser("mine", help="list your submissions on a hosted board (their state and reason)")
    lm.add_argument("--server", required=True, help="the hosted board's URL, e.g. http://127.0.0.1:8000")
    lm.add_argument("--token", default=None, help=f"your account's token (default: ${TOKEN_ENV})")


def upload(args: argparse.Namespace) -> int:
    """Pack, upload and follow a submission to a hosted board; its refusal or failure is one line, status 1."""
    from wfbench.leaderboard.server.client import UploadError, result_lines
    from wfbench.leaderboard.server.client import upload as send

    token = _token(args)
    try:
        sub = send(args.server, token, args.policy, args.track, phase=args.phase, name=args.name, entry=args.entry,
                   wait=not args.no_wait, progress=not args.no_progress)
    except UploadError as exc:
        print(f"wfbench: error: {exc}", file=sys.stderr)
        return EXIT_POLICY_FAILED
    print("\n".join(result_lines(sub)))
    return 0


def _token(args: argparse.Namespace) -> str:
    token = args.token or os.environ.get(TOKEN_ENV, "")
    if not token:
        raise UsageError(f"no token: pass --token or set ${TOKEN_ENV} (the board's admin makes one)")
    return token


def hosted(args: argparse.Namespace) -> int:
    """``mine`` and ``withdraw --server``: a hosted board's list of your submissions, or one withdrawn.

    The server's refusal is its one line, with status 1.
    """
    from wfbench.leaderboard.server.client import Client, UploadError, mine_lines

    if args.lb_command == "withdraw" and args.id is None:
        raise UsageError("--id is needed with --server: the submission to withdraw (see 'wfbench leaderboard mine')")
    token = _token(args)
    try:
        with Client(args.server, token) as client:
            if args.lb_command == "mine":
                print("\n".join(mine_lines(client.mine())))
                return 0
            sub = client.withdraw(args.id)
    except UploadError as exc:
        print(f"wfbench: error: {exc}", file=sys.stderr)
        return EXIT_POLICY_FAILED
    print(f"withdrew submission {sub['id']} ({sub['name']} on {sub['track']}, {sub['phase']} phase): it is off the "
          "board and its queued job is cancelled")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.lb_command == "upload":  # before the imports below: the client needs none of them
        return upload(args)
    if args.lb_command == "mine" or (args.lb_command == "withdraw" and args.server):
        return hosted(args)
    if args.lb_command == "withdraw" and (args.name is None or args.id is not None):
        raise UsageError("withdraw takes --name (an entry of the local store) or --server and --id (a hosted "
                         "submission)")
    # the report is imported here: it loads scipy.stats, which slows every start of the command line
    from wfbench.leaderboard.report import check_format
    from wfbench.leaderboard.store import Store, StoreError, show
    from wfbench.leaderboard.submit import SubmitError, describe, scenario_times, seed_builtins, seed_tracks, submit
    from wfbench.leaderboard.tracks import TRACKS, get_track

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
            execution = check_backend_args(args, progress=not args.no_progress)
            out = submit(tr, args.policy, args.name, submitter=args.submitter, db=args.db, execution=execution,
                         wall_time_s=args.wall_time, memory_mb=args.memory, act_timeout_s=args.act_timeout,
                         replace=args.replace)
            store = Store(args.db)
            if out.status == "complete":
                print(describe(out, tr, store.path))
                if times := scenario_times(out):
                    print(times)
                return 0
            if args.traceback and out.trace:
                print(out.trace, end="" if out.trace.endswith("\n") else "\n", file=sys.stderr)
            hint = "" if args.traceback or not out.trace else "; --traceback prints the whole trace"
            print(f"wfbench: {describe(out, tr, store.path, hint)}", file=sys.stderr)
            return EXIT_POLICY_FAILED
        if args.lb_command == "withdraw":
            tr = track(args.track)
            store = Store(args.db, create=False)
            n = store.withdraw(tr.name, args.name, args.reason)
            print(f"withdrew {args.name!r} from track {tr.name}: its entry and {n} rows moved to the audit tables "
                  f"of {store.path}")
            return 0
        if args.lb_command == "baselines":
            execution = check_backend_args(args, progress=not args.no_progress)
            failed = 0
            for tr in seed_tracks(track(args.track) if args.track else None):  # unseeded tracks: only when named
                for out in seed_builtins(tr, db=args.db, execution=execution):
                    print(f"{tr.name:<14s} {out.submission.name:<20s} {out.status} ({out.stored_rows} seeds, "
                          f"{out.new_rows} new, {out.seconds:.1f} s){': ' + out.reason if out.reason else ''}")
                    failed += out.status != "complete"
            return 1 if failed else 0
        # show
        tr = track(args.track)
        try:
            check_format(args.format, "--format")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        out_path = check_writable(args.out, "--out") if args.out else None
        board = show(tr, args.db, args.format, baseline=args.baseline, max_decision_ms=args.max_decision_ms,
                     max_cpu_s=args.max_cpu_s)
        for msg in board.refused:
            print(f"wfbench: warning: {msg}", file=sys.stderr)
        for msg in board.left_out:
            print(f"wfbench: left out by the budget: {msg}", file=sys.stderr)
        text = board.text
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
