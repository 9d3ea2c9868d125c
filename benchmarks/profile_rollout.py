"""Where a PPO update's time goes, by operator: ``torch.profiler`` over one rollout and one update.

    python benchmarks/profile_rollout.py [--scenario paper-64 | --scenarios suite-v1:train] [--shards 1]
                                         [--model scalefree] [--num-envs 4096]
                                         [--num-steps 32] [--device cpu|cuda] [--bf16] [--compile]
                                         [--rows 25] [--out table.txt]

One warm-up update (compilation, allocation), then one rollout and one update of the real
trainer (``wfbench.train.ppo.Trainer``) under the profiler, with CUDA's activity where the
device is CUDA. Prints the operators by total time on the device (CPU time on CPU), the
count of kernel launches per env-step, and the trainer's own split (simulator, forward,
update). ``benchmarks/train_speed.py`` gives the throughput; this says why
(docs/performance.md, "The GPU path").
"""

from __future__ import annotations

import argparse
import tempfile
import time

import torch
from torch.profiler import ProfilerActivity, profile

from wfbench.train.ppo import TrainConfig, Trainer


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--scenarios", default="", help="several worlds, as wfbench train --scenarios "
                    "(e.g. suite-v1:train)")
    ap.add_argument("--shards", type=int, default=1, help="the batch as this many shards, in this one process "
                    "(default 1: the profile of one process's whole batch)")
    ap.add_argument("--model", default="scalefree")
    ap.add_argument("--num-envs", type=int, default=4096)
    ap.add_argument("--num-steps", type=int, default=32)
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--bf16", action="store_true")
    ap.add_argument("--compile", action="store_true")
    ap.add_argument("--rows", type=int, default=25)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    cuda = a.device == "cuda"
    with tempfile.TemporaryDirectory() as tmp:
        cfg = TrainConfig(scenario=a.scenario, scenarios=a.scenarios, shards=a.shards, procs=1, model=a.model,
                          num_envs=a.num_envs, num_steps=a.num_steps,
                          steps=a.num_envs * a.num_steps * 3, eval_every=0, checkpoint_every=10**9, run_dir=tmp,
                          device=a.device, bf16=a.bf16, compile=a.compile)
        tr = Trainer(cfg, progress=False, log=False, amp=torch.bfloat16 if a.bf16 else None)
        tr.learn(tr.rollout())  # warm-up
        if cuda:
            torch.cuda.synchronize()
        for k in tr.timing:
            tr.timing[k] = 0.0
        activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if cuda else [])
        t0 = time.perf_counter()
        with profile(activities=activities) as prof:
            tr.learn(tr.rollout())
            if cuda:
                torch.cuda.synchronize()
        wall = time.perf_counter() - t0
    steps = a.num_envs * a.num_steps
    events = prof.key_averages()
    key = "self_device_time_total" if cuda else "self_cpu_time_total"
    table = events.table(sort_by=key, row_limit=a.rows)
    launches = sum(e.count for e in events if e.key in ("cudaLaunchKernel", "cuLaunchKernel", "cudaLaunchKernelExC"))
    split = "  ".join(f"{k} {v / wall:.0%}" for k, v in tr.timing.items())
    head = (f"{a.scenarios or a.scenario} {a.model} B={a.num_envs} T={a.num_steps} {a.device}"
            f"{' bf16' if a.bf16 else ''}"
            f"{' compiled' if a.compile else ''}: {steps / wall:,.0f} env-steps/s under the profiler; "
            f"{split}; kernel launches {launches} ({launches / a.num_steps:.0f} per rollout step incl. update)")
    text = head + "\n" + table
    print(text, flush=True)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text)
    return text


if __name__ == "__main__":
    main()
