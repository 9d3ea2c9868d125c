"""Training speed of the PPO trainer: env-steps/s and where the time goes, per model size.

    python benchmarks/train_speed.py [--scenario paper-64 | --scenarios suite-v1:train]
                                     [--models cpu,small,paper] [--threads 1,2]
                                     [--agents joint,independent] [--updates 2] [--num-envs 32]
                                     [--num-steps 32] [--epochs 2] [--minibatches 2]
                                     [--procs 1,2] [--shards 0]
                                     [--device cpu|cuda] [--bf16] [--compile] [--json out.json]

For each model and thread count: one warm-up update (compiles, allocates), then
``--updates`` timed updates of the real trainer (``wfbench.train.ppo.Trainer``: rollout
and PPO update, 2 epochs x 2 minibatches), split into the simulator (step and observe,
the heuristic parts of the dispatch variant included), observation -> tensors, the
rollout forward pass with sampling, and the update (forward and backward over the
rollout). ``--agents independent`` measures one network per decision (three networks).
Checkpoints and public-seed scoring are off. ``--scenarios`` trains across worlds as
``wfbench train --scenarios`` does (the training split: every batch holds every world).
Numbers go to docs/performance.md.

``--procs`` runs the trainer in 1 or 2 processes (``TrainConfig.procs``: data-parallel PPO,
the same weights either way; ``--shards``: the shards the batch is computed as, 0 auto: 2 from
32 environments on); the shares are rank 0's (its shard's rollout and its half of the
update) and ``cpu_s`` is rank 0's process alone. The second process starts before the
warm-up update and is not timed.

``--device cuda`` runs the trainer on the GPU (the clock is read after
``torch.cuda.synchronize()``; the row adds the GPU's name and its peak memory),
``--bf16`` its forward passes under bf16 autocast (on CPU too: ``torch.autocast("cpu")``,
the CUDA dtype path; off by default, as on CPU training) and ``--compile`` wraps the
network in ``torch.compile`` (the warm-up update then includes the compilation).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time

import torch
from wfbench.policies.neural.model import count_parameters

from wfbench.train.ppo import TrainConfig, Trainer


def measure(scenario: str, model: str, threads: int, updates: int, num_envs: int, num_steps: int,
            agents: str = "joint", device: str = "cpu", bf16: bool = False, compile: bool = False,
            scenarios: str = "", epochs: int = 2, minibatches: int = 2, procs: int = 1, shards: int = 0) -> dict:
    cuda = device == "cuda"

    def sync():
        if cuda:
            torch.cuda.synchronize()

    with tempfile.TemporaryDirectory() as tmp:
        cfg = TrainConfig(scenario=scenario, scenarios=scenarios, epochs=epochs, minibatches=minibatches,
                          model=model, num_envs=num_envs, num_steps=num_steps,
                          steps=num_envs * num_steps * (updates + 1), eval_every=0, checkpoint_every=10**9,
                          run_dir=tmp, threads=threads, device=device, agents=agents, bf16=bf16, compile=compile,
                          procs=procs, shards=shards)
        tr = Trainer(cfg, progress=False, log=False, amp=torch.bfloat16 if bf16 else None)
        try:
            tr.learn(tr.rollout())  # warm-up (and compilation)
            tr.update += 1
            sync()
            for k in tr.timing:
                tr.timing[k] = 0.0
            if cuda:
                torch.cuda.reset_peak_memory_stats()
            load0 = os.getloadavg()[0]
            t0, c0, steps0 = time.perf_counter(), time.process_time(), tr.run.global_step
            for _ in range(updates):
                tr.learn(tr.rollout())
                tr.update += 1
            sync()
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            steps = tr.run.global_step - steps0
        finally:
            tr.close()
    gpu = {}
    if cuda:
        gpu = {"gpu": torch.cuda.get_device_name(), "gpu_peak_gib": torch.cuda.max_memory_allocated() / 2**30}
    return {"scenario": scenarios or scenario, "epochs": epochs, "minibatches": minibatches, "model": model,
            "agents": agents, "parameters": count_parameters(tr.model), "procs": tr.group.procs,
            "shards": tr.group.shards,
            "threads": threads, "device": device, "bf16": bf16, "compile": compile, "num_envs": num_envs,
            "env_steps": steps, "wall_s": wall, "env_steps_per_s": steps / wall,
            "cpu_s": cpu, "env_steps_per_cpu_s": steps / cpu, "load_avg_before": load0,
            "load_avg_after": os.getloadavg()[0], **gpu, **{f"{k}_share": v / wall for k, v in tr.timing.items()}}


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--scenarios", default="", help="train across worlds, e.g. suite-v1:train (then --scenario "
                    "is unused)")
    ap.add_argument("--models", default="cpu,small,paper")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--agents", default="joint")
    ap.add_argument("--updates", type=int, default=2)
    ap.add_argument("--num-envs", type=int, default=32)
    ap.add_argument("--num-steps", type=int, default=32)
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--minibatches", type=int, default=2)
    ap.add_argument("--procs", default="1", help="processes, comma-separated: 1,2 (TrainConfig.procs)")
    ap.add_argument("--shards", type=int, default=0, help="shards of the batch (0: auto; TrainConfig.shards)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--bf16", action="store_true", help="bf16 autocast of the forward passes (CPU too)")
    ap.add_argument("--compile", action="store_true", help="torch.compile the network")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = []
    settings = [(m, g, int(t), int(p)) for m in a.models.split(",") for g in a.agents.split(",")
                for t in a.threads.split(",") for p in a.procs.split(",")]
    for _ in range(a.repeat):
        for model, agents, threads, procs in settings:
            r = measure(a.scenario, model, threads, a.updates, a.num_envs, a.num_steps, agents, a.device, a.bf16,
                        a.compile, a.scenarios, a.epochs, a.minibatches, procs, a.shards)
            rows.append(r)
            how = f"{a.device}{' bf16' if a.bf16 else ''}{' compiled' if a.compile else ''}"
            gpu = f"  GPU peak {r['gpu_peak_gib']:.1f} GiB" if "gpu_peak_gib" in r else ""
            print(f"{r['scenario']:9s} {r['num_envs']}x{a.num_steps} {a.epochs}x{a.minibatches} {r['model']:6s} "
                  f"{agents:11s} {how} {r['parameters']:>8,d} params  "
                  f"threads {threads}  procs {r['procs']} ({r['shards']} shards)  "
                  f"{r['env_steps_per_s']:7.0f} env-steps/s  simulator {r['simulator_share']:.0%}  "
                  f"obs->tensor {r['obs_to_tensor_share']:.0%}  forward {r['forward_share']:.0%}  "
                  f"update {r['update_share']:.0%}  ({r['env_steps_per_cpu_s']:.0f} per CPU-s, load "
                  f"{r['load_avg_before']:.1f}-{r['load_avg_after']:.1f}){gpu}", flush=True)
    machine = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
               "torch": torch.__version__, "load_avg_1min": os.getloadavg()[0],
               "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"), "device": a.device,
               **({"gpu": torch.cuda.get_device_name()} if a.device == "cuda" else {})}
    print(json.dumps(machine))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"machine": machine, "rows": rows, "num_envs": a.num_envs, "num_steps": a.num_steps,
                       "epochs": a.epochs, "minibatches": a.minibatches}, fh,
                      indent=2)
    return rows


if __name__ == "__main__":
    main()
