"""What one greedy step on a network's own hindsight action values would gain (docs/hindsight-learning.md).

The network (a ``ppo:``-style checkpoint, ``ppo-joint`` by default) plays training
episodes of ``--scenario``; every ``--every`` steps, at each environment's state, its
workforce action values are computed twice with independent noise
(``wfbench.train.hindsight.Trainer.learner_values``: each action taken in copies of the
environment, the network acting afterwards on the known future). The action best by the
first estimate is scored by the second, so the noise of the choice does not inflate the
score: the mean of ``A2[argmax A1] - sum_a pi(a) A2(a)`` over the states is what a
greedy step would gain there, in NSW summed over ``--horizon`` steps.

    .venv/bin/python benchmarks/learner_values_gain.py --states 6 --samples 8 --horizon 120

The numbers quoted in docs/hindsight-learning.md ("The learner's own action values")
come from this command (96 states, 2 minutes on the 2-core VM).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from wfbench.policies.neural.dist import gumbel, noise_shapes, sample
from wfbench.policies.neural.model import featurize, obs_to_torch
from wfbench.policies.registry import checkpoint_file

from wfbench.scenarios.resolve import resolve_scenario
from wfbench.train.hindsight import HindsightConfig, Trainer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(checkpoint_file("ppo-joint")))
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--model", default="cpu", help="the checkpoint's model preset")
    ap.add_argument("--envs", type=int, default=16)
    ap.add_argument("--every", type=int, default=32, help="steps between two scored times")
    ap.add_argument("--states", type=int, default=6, help="scored times (each scores every environment)")
    ap.add_argument("--samples", type=int, default=8, help="roll-forwards per action in each estimate")
    ap.add_argument("--horizon", type=int, default=120)
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args()
    steps = resolve_scenario(a.scenario).horizon
    if a.states * a.every >= steps:  # every scored time within the first episode: a finished one has no future
        ap.error(f"--states {a.states} x --every {a.every} = {a.states * a.every} is not allowed; allowed: fewer "
                 f"than the episode's {steps} steps of {a.scenario}")
    cfg = HindsightConfig(scenario=a.scenario, model=a.model, device="cpu", num_envs=a.envs, num_steps=a.every,
                          burn_in=0, beta0=0.0, value_horizon=a.horizon, value_samples=a.samples, seed=a.seed,
                          init=a.checkpoint, eval_every=0, run_dir="/tmp/learner_values_gain")
    tr = Trainer(cfg, progress=False, log=False)  # workforce_target "action": collect() computes no values
    gains, own, picks, noop = [], [], [], []
    start = time.perf_counter()
    for _ in range(a.states):
        tr.collect(0.0)  # the network plays `every` steps
        x = featurize(obs_to_torch(tr.obs, tr.run.device), tr.run.network.coord_scale)
        with torch.no_grad():
            out, state = tr.model(x, tr.state, torch.zeros(1, a.envs))
            logits = out["workforce"].float().masked_fill(x["workforce_mask"] <= 0, -1e9)
            pi = torch.softmax(logits, -1).numpy()
            noise = {key: gumbel(shape, tr.gen) for key, shape in noise_shapes(a.envs, tr.sim.M, tr.sim.N).items()}
            mine = {key: v.numpy() for key, v in sample(out, x, noise).items()}
        before, tr.state = tr.state, state  # learner_values starts from the memory after this step's input
        first, second = tr.learner_values(mine), tr.learner_values(mine)
        tr.state = before
        allowed = ~np.isnan(first)
        best = np.argmax(np.where(allowed, first, -np.inf), axis=1)
        v2 = np.where(allowed, second, 0.0)
        mean_pi = (pi * v2).sum(axis=1)
        gains += list(v2[np.arange(a.envs), best] - mean_pi)
        own += list(mean_pi)
        picks += list(best)
        noop += list(pi[:, 0])
        print(f"time {int(tr.obs['t'][0])}: {len(gains)} states, {time.perf_counter() - start:.0f} s", flush=True)
    g, o = np.array(gains), np.array(own)
    n = len(g)
    print(f"{n} states; greedy step minus the network's distribution: {g.mean():+.4f} (standard error "
          f"{g.std(ddof=1) / np.sqrt(n):.4f}) NSW summed over {a.horizon} steps, {g.mean() / a.horizon:+.5f} a step")
    print(f"the network's distribution minus the no-op: {o.mean():+.4f} "
          f"(standard error {o.std(ddof=1) / np.sqrt(n):.4f})")
    print(f"greedy choice per workforce code: {np.bincount(picks, minlength=7).tolist()}; "
          f"mean probability of the no-op: {np.mean(noop):.3f}")


if __name__ == "__main__":
    main()
