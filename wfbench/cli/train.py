"""``wfbench train``: train a network with one of the algorithms of :mod:`wfbench.train.registry`.

The algorithms, ``--algo``'s choices and its help come from
:data:`wfbench.train.registry.ALGORITHMS`, which imports no torch; torch is imported
when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from wfbench.cli.common import UsageError, nonneg, positive, seeds_spec
from wfbench.train.registry import ALGORITHMS, DEFAULT_ALGORITHM, get_algorithm

# the flags that set a field of the same name in the algorithm's config (when given)
TRAIN_FLAGS = ("variant", "scenario", "scenarios", "steps", "model", "num_envs", "num_steps", "epochs", "minibatches",
               "lr", "ent_coef", "seed", "device", "threads", "checkpoint_every", "eval_every", "eval_seeds", "run_dir",
               "init", "gae_lambda", "gamma", "agents", "address", "teacher", "procs")


def add_parser(sub) -> None:
    names = ", ".join(ALGORITHMS)
    tr = sub.add_parser("train", help=f"train a policy ({names}; docs/rl.md); needs torch (the rl extra)")
    tr.add_argument("--algo", default=None, choices=list(ALGORITHMS),
                    help="; ".join(f"{a.name}{' (default)' if a.name == DEFAULT_ALGORITHM else ''}: {a.summary}"
                                   for a in ALGORITHMS.values())
                    + "; docs/rl.md, docs/impala.md, docs/hindsight-learning.md")
    tr.add_argument("--variant", default=None, choices=["joint", "dispatch"],
                    help="joint: all three decisions; dispatch: the dispatch head only, heuristic workforce and "
                         "positioning (default joint)")
    tr.add_argument("--scenario", default=None, help="scenario to train on (default paper-64)")
    tr.add_argument("--scenarios", default=None, metavar="SPEC",
                    help="train across worlds instead: a suite's training split and/or scenarios, comma-separated, "
                         "e.g. suite-v1:train (held-out scenarios are refused); every batch holds every world, "
                         "rewards normalized per world, best.pt chosen on the mean normalized score of the worlds' "
                         "public seeds (docs/rl.md, Generalists)")
    tr.add_argument("--steps", type=positive, default=None, help="environment steps in all (default 1000000)")
    tr.add_argument("--model", default=None,
                    help="network: scalefree (observation version 2, any world size; the default of every "
                         "algorithm's joint network; docs/rl.md), or a preset of the paper's network: cpu (no "
                         "attention, fastest on CPU), tiny, small or paper (~0.5M parameters); the default of "
                         "--variant dispatch and --agents independent is their config's")
    tr.add_argument("--num-envs", type=positive, default=None,
                    help="environments side by side (default 32; ppo across worlds, --scenarios: 16 per world)")
    tr.add_argument("--num-steps", type=positive, default=None, help="steps per rollout (default 32)")
    tr.add_argument("--epochs", type=positive, default=None, help="PPO epochs per rollout (default 2)")
    tr.add_argument("--minibatches", type=positive, default=None, help="minibatches of whole sequences (default 2)")
    tr.add_argument("--lr", type=float, default=None, help="Adam learning rate (default 3e-4)")
    tr.add_argument("--ent-coef", type=float, default=None, help="entropy bonus (default 0.003)")
    tr.add_argument("--seed", type=nonneg, default=None, help="run seed: network init, sampling, training seeds")
    tr.add_argument("--device", default=None, choices=["auto", "cpu", "cuda"], help="default auto")
    tr.add_argument("--compile", action="store_true", help="torch.compile the network (made for CUDA)")
    tr.add_argument("--no-bf16", action="store_true", help="no bf16 autocast on CUDA")
    tr.add_argument("--threads", type=positive, default=None, help="torch CPU threads (default 1)")
    tr.add_argument("--procs", type=nonneg, default=None,
                    help="ppo: processes computing the batch's shards, 1 or 2 (the same weights either way); default 0 "
                         "(auto): 2 on a CPU with 2 cores or more when the batch has 2 shards (64 environments or "
                         "more, split evenly), else 1; docs/rl.md, Shards and processes")
    tr.add_argument("--checkpoint-every", type=positive, default=None, help="updates between checkpoints (20)")
    tr.add_argument("--eval-every", type=nonneg, default=None,
                    help="updates between scores on the public seeds that pick best.pt (default 20; 0: never)")
    tr.add_argument("--eval-seeds", type=seeds_spec, default=None,
                    help="public seeds that select the checkpoint (default public:10; test seeds are refused)")
    tr.add_argument("--run-dir", default=None, help="folder of the run (default runs/ALGO-VARIANT-SCENARIO, e.g. "
                    f"runs/{DEFAULT_ALGORITHM}-joint-paper-64)")
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
    tr.add_argument("--teacher", default=None, metavar="NAME",
                    help="distill: the deployable policy the network imitates on its own states (default "
                         "rollout-solver-tuned-1ms; a policy that reads the future is refused: that is --algo "
                         "hindsight); hindsight: oracle or nearest+oracle+oracle; docs/rl.md, Distillation")
    tr.add_argument("--resume", default=None, metavar="CKPT",
                    help="continue a run from its checkpoint (latest.pt); its settings are kept, --steps may raise "
                         "the total")
    tr.add_argument("--set", action="append", metavar="KEY=VALUE",
                    help="any other setting of the algorithm's config (repeatable), e.g. --set rho_bar=0.9")
    tr.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    tr.add_argument("--no-tensorboard", action="store_true", help="write no TensorBoard logs")


def default_model(config_cls: type, given: dict) -> str:
    """The network of a ``wfbench train`` without ``--model``: the scale-free one where the trainer trains it.

    That is the joint network of PPO, IMPALA and hindsight learning (issue #44); ``--variant
    dispatch`` and ``--agents independent`` keep their config's default. The older networks
    stay available by name (``--model small``).
    """
    from wfbench.policies.neural.scalefree import ARCH

    joint = given.get("variant", "joint") == "joint" and given.get("agents", "joint") == "joint"
    return ARCH if config_cls.scalefree_ok and joint else config_cls().model


def default_num_envs(config_cls: type, given: dict) -> int | None:
    """The batch of a ``wfbench train --scenarios`` without ``--num-envs``: ``envs_per_world`` per world.

    For a trainer whose every batch holds every world (PPO: ``TrainConfig.envs_per_world``);
    None (the config's default) for one world, or a trainer that takes the worlds in turn.
    """
    per_world = config_cls.envs_per_world
    if per_world is None or not given.get("scenarios"):
        return None
    from wfbench.train.worlds import world_set

    return per_world * len(world_set(given["scenarios"]).worlds)


def two_processes_likely(args: argparse.Namespace) -> bool:
    """Whether the run will likely train in two processes: PPO across worlds or of 64 environments or more, on CPU.

    Then its second process starts ahead and imports meanwhile (:mod:`wfbench.train.standby`);
    a guess that the settings then prove wrong costs a process that ends unused.
    """
    from wfbench.train.standby import AUTO_SHARD_ENVS, usable_cores

    return (not args.resume and (args.algo or DEFAULT_ALGORITHM) == "ppo" and args.procs in (None, 0, 2)
            and args.device in (None, "auto", "cpu") and usable_cores() >= 2
            and (bool(args.scenarios) if args.num_envs is None else args.num_envs >= AUTO_SHARD_ENVS))


def run(args: argparse.Namespace) -> int:
    from wfbench.train import standby

    if two_processes_likely(args):  # before torch's import, which it overlaps
        standby.start("wfbench.train.ppo")
    try:
        return _run(args)
    finally:
        standby.release()


def _run(args: argparse.Namespace) -> int:
    from wfbench.cli.settings import train_settings

    try:  # torch is needed here only: the rest of the command line works without it
        import torch  # noqa: F401
    except ImportError as exc:
        raise UsageError(f"wfbench train needs torch ({exc}); install the rl extra: "
                         "pip install 'wfbench[rl]'") from None
    from wfbench.train.runs import SettingsError, fit, resumed_algorithm

    given = {flag: getattr(args, flag) for flag in TRAIN_FLAGS if getattr(args, flag) is not None}
    if args.compile:
        given["compile"] = True
    if args.no_bf16:
        given["bf16"] = False
    try:  # the algorithm first: it types the --set values (a resumed run's is its checkpoint's)
        algo = resumed_algorithm(args.resume, args.algo) if args.resume else (args.algo or DEFAULT_ALGORITHM)
        given = train_settings(get_algorithm(algo).config_class(), given, algo, args.set or [])
        if not args.resume and "model" not in given:
            given["model"] = default_model(get_algorithm(algo).config_class(), given)
        if not args.resume and "num_envs" not in given:
            envs = default_num_envs(get_algorithm(algo).config_class(), given)
            if envs is not None:
                given["num_envs"] = envs
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    try:
        trainer = fit(algo, resume=args.resume, progress=not args.no_progress, log=not args.no_tensorboard, **given)
    except SettingsError as exc:  # refused before training started
        raise UsageError(str(exc)) from None
    run = trainer.run
    config, best = run.config, run.best
    print(f"trained {run.global_step} environment steps ({algo}) in {config.run_dir}")
    best_pt = Path(config.run_dir) / "best.pt"
    if best["update"] is not None:
        what = "mean normalized score over the worlds" if config.scenarios else "mean NSW"
        print(f"best.pt: update {best['update']}, {what} {best['score']:.4f} on public seeds "
              f"{best['seeds'][0]}-{best['seeds'][-1]} ({best['mode']}); evaluate with "
              f"wfbench evaluate --policy {algo}:{best_pt}")
    else:  # save_unselected_best wrote the last weights as best.pt (docs/rl.md)
        why = "--eval-every 0" if not config.eval_every else f"fewer than --eval-every {config.eval_every} updates"
        print(f"best.pt: the last weights, not selected (no evaluation on the public seeds ran: {why}); evaluate "
              f"with wfbench evaluate --policy {algo}:{best_pt}")
    print(f"latest.pt: {Path(config.run_dir) / 'latest.pt'}")
    return 0
