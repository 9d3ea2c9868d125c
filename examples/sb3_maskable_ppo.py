"""Train sb3-contrib's MaskablePPO on ``small`` through the batched SB3 VecEnv, then score it with wfbench.

The agent learns the dispatch decision (``kind="dispatch"``: the workforce and
positioning decisions are the paper's heuristics, as in ``wfbench/Dispatch-v0``) with
the entity-set features extractor; all ``--envs`` environments step in one compiled
call. The trained model is wrapped as a wfbench policy and scored by
``wfbench.evaluate`` on test seeds beside random dispatch and the built-in heuristic
(nearest dispatch), both with the same workforce and positioning (``docs/sb3.md``).

Usage::

    python examples/sb3_maskable_ppo.py --timesteps 4096 --envs 16 --eval-seeds 10

Needs the ``rl`` extra (torch, stable-baselines3, sb3-contrib).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from sb3_contrib import MaskablePPO
from wfbench.policies import Composite

import wfbench
from wfbench.core.seeds import TRAIN_START
from wfbench.envs.sb3 import EntitySetExtractor, SB3Policy, WorkforceVecEnv


def main(argv: list[str] | None = None) -> dict[str, float]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="small")
    ap.add_argument("--timesteps", type=int, default=4096, help="environment steps of training (all envs)")
    ap.add_argument("--envs", type=int, default=16, help="environments in the batch")
    ap.add_argument("--eval-seeds", type=int, default=10, help="test seeds 0..n-1 to score on")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)  # small networks: threads cost more than they give

    env = WorkforceVecEnv(args.scenario, args.envs, kind="dispatch")
    model = MaskablePPO(
        "MultiInputPolicy", env, n_steps=64, batch_size=256, n_epochs=4, learning_rate=3e-4, gamma=0.99,
        seed=args.seed, device="cpu", verbose=0,
        policy_kwargs={"features_extractor_class": EntitySetExtractor,
                       "features_extractor_kwargs": {"hidden": 32, "features_dim": 64},
                       "net_arch": [64]},
    )
    # SB3 seeds the environments with the model's seed (env.seed(seed): seeds seed + i, test
    # seeds here); training episodes belong on the train set, so seed them after the model
    env.seed(TRAIN_START + args.seed * args.envs)
    start = time.perf_counter()
    model.learn(args.timesteps)
    train_s = time.perf_counter() - start

    trained = Composite(dispatch=SB3Policy(model, args.scenario, kind="dispatch", name="maskable-ppo"),
                        workforce="threshold", positioning="spatial", name="maskable-ppo+threshold+spatial")
    seeds = list(range(args.eval_seeds))
    random_dispatch = Composite(dispatch="random", workforce="threshold", positioning="spatial",
                                name="random+threshold+spatial")
    scores = {name: float(wfbench.evaluate(p, args.scenario, seeds=seeds)["nsw"].mean())
              for name, p in (("maskable-ppo", trained), ("random dispatch", random_dispatch),
                              ("heuristic", "heuristic"))}
    steps = model.num_timesteps
    print(f"{args.scenario}: {steps} env-steps in {train_s:.1f} s ({steps / train_s:,.0f} env-steps/s, "
          f"{args.envs} envs in one batch)")
    for name, nsw in scores.items():
        print(f"  NSW on test seeds 0-{args.eval_seeds - 1}: {name:<15} {nsw:.4f}")
    return {**scores, "env_steps": float(steps), "train_s": train_s, "steps_per_s": steps / train_s,
            "finite": float(np.isfinite(list(scores.values())).all())}


if __name__ == "__main__":
    main()
