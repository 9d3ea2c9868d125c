"""``wfbench tune``: search a policy's tunable parameters on public seeds and write a tuned-policy file."""

from __future__ import annotations

import argparse
import shlex
import sys

from wfbench.cli.common import (
    SCENARIO_HELP,
    UsageError,
    add_backend_args,
    check_backend_args,
    check_writable,
    nonneg,
    positive,
    resolve_policy,
    resolve_scenario,
    seeds_spec,
)


def add_parser(sub) -> None:
    t = sub.add_parser("tune", help="search a policy's tunable parameters on public seeds (Optuna TPE) and write "
                       "a tuned-policy file")
    t.add_argument("policy", help="registry name or D+W+P composite whose parts declare parameters (heuristic, "
                   "solver, ...)")
    t.add_argument("--scenario", default=None, help=f"{SCENARIO_HELP} (default paper-64)")
    t.add_argument("--scenarios", default=None, metavar="SPEC",
                   help="tune across worlds instead: a suite's training split or its training scenarios, "
                        "comma-separated, e.g. suite-v1:train (held-out scenarios are refused); the objective is "
                        "then the mean over the worlds of each one's normalized score (docs/suite.md), as the "
                        "generalist networks are selected on")
    t.add_argument("--trials", type=positive, default=100,
                   help="the study's total of finished trials (default 100); re-run the same command to resume, "
                        "raise it to extend")
    t.add_argument("--seeds", type=seeds_spec, default="public",
                   help="tuning seeds: public (default, 1000-1049), public:N or train:N; test seeds are refused")
    t.add_argument("--params", default=None,
                   help="comma-separated parameters to search, each optionally narrowed as name=low:high "
                        "(default: all the policy declares; --list shows them)")
    t.add_argument("--list", action="store_true", help="list the policy's tunable parameters and ranges, and exit")
    t.add_argument("--study-db", default="wfbench-tune.db", help="SQLite file of the study (default "
                   "./wfbench-tune.db)")
    t.add_argument("--study-name", default=None, help="the study's name in it (default POLICY@SCENARIO, or "
                   "POLICY@SPEC with --scenarios)")
    t.add_argument("--sampler-seed", type=nonneg, default=0, help="seed of the TPE sampler (default 0)")
    t.add_argument("--name", default=None, help="the tuned policy's name (default POLICY-tuned)")
    t.add_argument("--out", default=None, help="tuned-policy file, .json or .toml (default "
                   "./tuned-POLICY-SCENARIO.json; with --scenarios suite-v1:train, ./tuned-POLICY-suite-v1-train.json)")
    t.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    add_backend_args(t)


def run(args: argparse.Namespace) -> int:
    from wfbench.train.worlds import world_set
    from wfbench.tune import check_tuning_seeds, search_space, tune, tuning_worlds
    from wfbench.tune.search import check_scenario_args, default_out, default_study_name

    policy = resolve_policy(args.policy)
    if args.list:
        try:
            space = search_space(policy)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        current = policy.params()
        for key, p in space.items():
            print(f"{key:<30s} {p.describe():<36s} now {current[key]:g}")
        return 0
    given = args.scenario or ("paper-64" if args.scenarios is None else None)  # neither: paper-64
    try:
        check_scenario_args(given, args.scenarios, ("--scenario", "--scenarios"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    scenarios = None
    if args.scenarios is not None:
        try:
            scenarios = world_set(args.scenarios)
            worlds = tuning_worlds(scenarios)
        except ValueError as exc:
            raise UsageError(f"--scenarios: {exc}") from None
        where, scenario, judge = f"{args.scenarios} ({len(worlds)} worlds)", None, f"--suite {worlds[0].suite}"
        slug = args.scenarios
    else:
        scenario = resolve_scenario(given)  # resolved once, here; tune() records it by its name
        where = slug = scenario.name
        judge = f"--scenario {given}"
    execution = check_backend_args(args, progress=not args.no_progress)
    try:
        seeds = check_tuning_seeds(args.seeds)
    except ValueError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    out = args.out or str(default_out(args.policy, slug))  # tune()'s default, named here to check it first
    check_writable(out, "--out")
    check_writable(args.study_db, "--study-db")
    command = "wfbench " + shlex.join(args.argv)
    try:
        r = tune(args.policy, scenario, args.trials, seeds=seeds, params=args.params, study_db=args.study_db,
                 study_name=args.study_name, execution=execution, sampler_seed=args.sampler_seed, out=out,
                 name=args.name, command=command, scenarios=scenarios)
    except KeyboardInterrupt:
        print(f"wfbench: interrupted; the finished trials are kept in {args.study_db} (study "
              f"{args.study_name or default_study_name(args.policy, args.scenarios or scenario.name)!r}): run the "
              "same command again to resume", file=sys.stderr)
        return 130
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    t = r.tuned
    what = "mean NSW" if args.scenarios is None else "mean normalized score"
    untuned = f", untuned {r.untuned_score:.4f}" if r.untuned_score is not None else ""
    print(f"{t.name}: best {what} {t.best_score:.4f}{untuned} on {where} seeds {t.seed_set}, "
          f"{t.trials} trials ({r.new_trials} new) in {r.study_db} study {r.study_name!r}")
    for k, v in t.params.items():
        print(f"  {k} = {v:g}")
    print(f"wrote {r.path}; judge it on the test seeds: wfbench compare --policies {args.policy},{r.path} "
          f"{judge} --seeds test")
    return 0
