"""What a distillation teacher's labels cost: CPU ms per labelled env-step, per world of the training split.

Distillation (``wfbench train --algo distill``) asks its teacher for a label at every step of
every environment; this plays the teacher alone (its own play, as the demonstration batches
do) on ``--envs`` training seeds of each world for ``--steps`` steps, and prints the CPU
milliseconds per env-step of its ``act`` (the label) beside the simulator's step. The
first episode of a world pays numba's compile of the teacher's kernels: ``--warmup`` steps
of a first batch are played and not counted.

    python benchmarks/distill_labels.py --teacher rollout-solver-tuned-1ms --steps 200 --envs 16
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from wfbench.core.simulator import Simulator
from wfbench.train.collection import take_seeds
from wfbench.train.distill import Teacher, teacher_policy
from wfbench.train.worlds import world_set


def measure(teacher: str, spec: str, steps: int, envs: int, warmup: int) -> list[dict]:
    rows = []
    for w in world_set(spec).worlds:
        config = w.config
        if warmup:
            sim = Simulator(config, take_seeds(0, 10_000, 1), keep_series=False, threads=1)
            obs, label = sim.reset(), Teacher(teacher_policy(teacher), config, sim.seeds.tolist())
            for _ in range(min(warmup, config.horizon)):
                obs = sim.step_observe(label.act(obs))[1]
        seeds = take_seeds(0, 0, envs)
        sim = Simulator(config, seeds, keep_series=False, threads=1)
        obs = sim.reset()
        label = Teacher(teacher_policy(teacher), config, seeds)
        act_cpu = sim_cpu = 0.0
        n = min(steps, config.horizon)
        for _ in range(n):
            c0 = time.process_time()
            action = label.act(obs)
            c1 = time.process_time()
            obs = sim.step_observe(action)[1]
            act_cpu += c1 - c0
            sim_cpu += time.process_time() - c1
        rows.append({"world": w.name, "env_steps": n * envs, "label_cpu_ms_per_env_step": 1e3 * act_cpu / (n * envs),
                     "sim_cpu_ms_per_env_step": 1e3 * sim_cpu / (n * envs)})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--teacher", default="rollout-solver-tuned-1ms")
    ap.add_argument("--scenarios", default="suite-v1:train")
    ap.add_argument("--steps", type=int, default=200, help="steps per world (of its horizon)")
    ap.add_argument("--envs", type=int, default=16, help="environments side by side (distill's num_envs)")
    ap.add_argument("--warmup", type=int, default=2, help="steps of a first, uncounted batch per world (compile)")
    args = ap.parse_args()
    rows = measure(args.teacher, args.scenarios, args.steps, args.envs, args.warmup)
    per = np.mean([r["label_cpu_ms_per_env_step"] for r in rows])
    print(json.dumps({"teacher": args.teacher, "mean_label_cpu_ms_per_env_step": per}))


if __name__ == "__main__":
    main()
