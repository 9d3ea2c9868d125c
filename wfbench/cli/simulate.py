"""``wfbench simulate``: run one episode, optionally render it to a GIF (:func:`wfbench.simulate`)."""

from __future__ import annotations

import argparse

from wfbench.cli.common import UsageError, add_policy_run_args, check_writable, nonneg, positive, resolve_scenario


def add_parser(sub) -> None:
    m = sub.add_parser("simulate", help="run one episode, optionally render it to a GIF")
    m.add_argument("--scenario", default="paper-64")
    m.add_argument("--seed", type=nonneg, default=0)
    m.add_argument("--policy", default="heuristic")
    m.add_argument("--render", default=None, help="write an animated GIF here")
    m.add_argument("--every", type=positive, default=4, help="one frame every this many steps (default 4)")
    m.add_argument("--steps", type=positive, default=None, help="stop after this many steps")
    add_policy_run_args(m)
    m.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    from wfbench.harness.guard import PolicyLoadError
    from wfbench.harness.simulate import simulate

    config = resolve_scenario(args.scenario)
    out = check_writable(args.render, "--render") if args.render else None
    try:
        episode = simulate(args.policy, config, args.seed, steps=args.steps, render=out, every=args.every,
                           act_timeout_s=args.act_timeout, progress=not args.no_progress)
    except PolicyLoadError as exc:  # a spec that names no policy; a policy that fails is a PolicyError
        raise UsageError(str(exc)) from None
    print(f"{config.name} seed {args.seed}, {args.policy}, {episode.steps} steps: "
          + ", ".join(f"{k}={v:.4g}" for k, v in episode.kpis.items()))
    if out:
        print(f"wrote {episode.frames} frames to {out}")
    return 0
