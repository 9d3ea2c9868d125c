"""Env-steps/s of sb3-contrib's MaskablePPO through the batched SB3 VecEnv vs the single-env path (docs/sb3.md).

Paths, each training the same MaskablePPO (``EntitySetExtractor``, the hyperparameters of
``examples/sb3_maskable_ppo.py``, rollouts of ``--rollout`` env-steps per update):

- ``single``: ``DummyVecEnv([Dispatch-v0])``, one environment, one Python step per env-step
  (the path used before ``wfbench.envs.sb3``);
- ``dummy-B``: ``DummyVecEnv`` of B single environments (B Python steps per vector step);
- ``batched-B``: ``WorkforceVecEnv`` with B environments in one simulator (one compiled call).

For each, ``learn`` env-steps/s (rollouts and updates) and ``env`` env-steps/s (the
vector environment alone: masked random actions, masks read every step, as MaskablePPO
does). torch runs on one thread.

Usage::

    python benchmarks/sb3_throughput.py --scenario small --envs 16 --timesteps 4096
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="small")
    ap.add_argument("--envs", type=int, default=16)
    ap.add_argument("--timesteps", type=int, default=4096)
    ap.add_argument("--rollout", type=int, default=1024, help="env-steps per PPO update (n_steps x envs)")
    ap.add_argument("--paths", default="single,dummy,batched")
    args = ap.parse_args()

    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from wfbench.envs.gym_env import DispatchEnv
    from wfbench.envs.sb3 import EntitySetExtractor, WorkforceVecEnv

    torch.set_num_threads(1)
    print(f"{args.scenario}, {args.timesteps} env-steps, rollout {args.rollout}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")

    def make(path: str):
        if path == "single":
            env = DummyVecEnv([lambda: DispatchEnv(args.scenario)])
        elif path == "dummy":
            env = DummyVecEnv([lambda: DispatchEnv(args.scenario)] * args.envs)
        else:
            env = WorkforceVecEnv(args.scenario, args.envs, kind="dispatch", threads=1)
        env.seed(1_000_000)
        return env

    for path in args.paths.split(","):
        label = path if path == "single" else f"{path}-{args.envs}"
        env = make(path)
        n = env.num_envs
        env.reset()
        rng = np.random.default_rng(0)
        nvec = env.action_space.nvec
        start, steps = time.perf_counter(), 0
        while time.perf_counter() - start < 5.0:
            masks = np.stack(env.env_method("action_masks")).reshape(n, len(nvec), -1)
            # a random allowed choice per facility: the no-op (last) or an allowed person
            a = np.argmax(np.where(masks, rng.random(masks.shape), -1.0), axis=-1)
            env.step(a)
            steps += n
        env_rate = steps / (time.perf_counter() - start)
        train_env = make(path)
        model = MaskablePPO("MultiInputPolicy", train_env, n_steps=max(1, args.rollout // n), batch_size=256,
                            n_epochs=4, seed=0, device="cpu",
                            policy_kwargs={"features_extractor_class": EntitySetExtractor,
                                           "features_extractor_kwargs": {"hidden": 32, "features_dim": 64},
                                           "net_arch": [64]})
        train_env.seed(1_000_000)  # after the model, which seeds the env with its own seed
        start = time.perf_counter()
        model.learn(args.timesteps)
        learn_rate = model.num_timesteps / (time.perf_counter() - start)
        print(f"{label:>12}: learn {learn_rate:8.1f} env-steps/s   env alone {env_rate:9.1f} env-steps/s")


if __name__ == "__main__":
    main()
