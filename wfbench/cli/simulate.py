"""``wfbench simulate``: run one episode, optionally render it to a GIF."""

from __future__ import annotations

import argparse

from wfbench.cli.common import check_writable, nonneg, positive, resolve_policy, resolve_scenario


def add_parser(sub) -> None:
    m = sub.add_parser("simulate", help="run one episode, optionally render it to a GIF")
    m.add_argument("--scenario", default="paper-64")
    m.add_argument("--seed", type=nonneg, default=0)
    m.add_argument("--policy", default="heuristic")
    m.add_argument("--render", default=None, help="write an animated GIF here")
    m.add_argument("--every", type=positive, default=4, help="one frame every this many steps (default 4)")
    m.add_argument("--steps", type=positive, default=None, help="stop after this many steps")
    m.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    from wfbench.core.kpis import KPI_NAMES
    from wfbench.core.simulator import Simulator
    from wfbench.envs.render import Renderer, save_gif

    config = resolve_scenario(args.scenario)
    policy = resolve_policy(args.policy)
    out = check_writable(args.render, "--render") if args.render else None
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
          + ", ".join(f"{k}={means[k][0]:.4g}" for k in KPI_NAMES))
    if out:
        save_gif(frames, out)
        print(f"wrote {len(frames)} frames to {out}")
    return 0
