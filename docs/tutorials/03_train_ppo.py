# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Train PPO on CPU
#
# This notebook trains the paper's joint model (one network for dispatch, workforce and
# positioning) with PPO on the `small` scenario, on the CPU, for a minute or more; then it
# evaluates the best checkpoint as a policy, plots the learning curve, and shows the
# command that runs the same training on a GPU. [PPO and `wfbench train`](../../rl/)
# describes the network, the trainer and every setting. It needs the `rl` extra
# (torch, TensorBoard): `pip install -e ".[rl]"`.
#
# Source: [03_train_ppo.py](03_train_ppo.py), a jupytext file
# ([how to open it](../01_evaluate_and_compare/)).
#
# **How long.** `TRAIN_STEPS` below sets the length: 65,536 environment steps by
# default, which took 1.2 minutes on two otherwise idle cores (5 with other jobs
# sharing them), the whole notebook under two. The test suite sets
# `WFBENCH_TUTORIAL_QUICK=1`, which trains for 4,096 steps instead, with the same code.
# On the CPU a run is deterministic given its seed (on the same torch build). The
# default run brings the network to the heuristic's level on `small` (+0.007 NSW on the
# 50 test seeds, 95% interval [-0.003, +0.017]: no difference the seeds support) with
# its public score still rising, so a longer run is the next step; the quick run stays
# below the heuristic. For scale, the shipped `ppo-joint` trained for 33 minutes on
# `paper-64` before its best checkpoint, and beats the heuristic there by 0.06.

# %%
import os
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

import wfbench
from wfbench import policies
from wfbench.harness.compare import compare, format_comparison
from wfbench.train.ppo import TrainConfig, Trainer

QUICK = os.environ.get("WFBENCH_TUTORIAL_QUICK") == "1"
TRAIN_STEPS = 4_096 if QUICK else 65_536  # environment steps in all: 16 environments x 32 steps per update
EVAL_EVERY = 8 if QUICK else 16  # updates between scores on the public seeds (they pick best.pt)
SEEDS = 10 if QUICK else 50  # the first N test seeds, for the final evaluation
run_dir = Path(tempfile.mkdtemp(prefix="wfbench-tutorial-")) / "ppo-small"

# %% [markdown]
# ## Training
#
# `TrainConfig` holds every setting (the same names as the flags of `wfbench train`),
# and `Trainer(config).train()` runs it. The `cpu` network is the paper's model without
# its attention layers, the fastest on a CPU. Every `eval_every` updates the network is
# scored on a few **public** seeds (1000-1049; the test seeds are refused), sampled and
# greedy, and the best sampled score is kept as `best.pt`.

# %%
config = TrainConfig(scenario="small", model="cpu", device="cpu", steps=TRAIN_STEPS, num_envs=16, num_steps=32,
                     epochs=2, minibatches=2, eval_every=EVAL_EVERY, eval_seeds="public:4",
                     checkpoint_every=1_000, seed=0, run_dir=str(run_dir))
trainer = Trainer(config, progress=False)  # progress=True shows a progress bar
start = time.perf_counter()
last = trainer.train()
minutes = (time.perf_counter() - start) / 60
print(f"{trainer.run.global_step} environment steps in {minutes:.1f} min "
      f"({trainer.run.global_step / (minutes * 60):.0f} steps/s), {trainer.update} updates")
print("last update:", {k: round(v, 4) for k, v in last.items()})
print("best checkpoint:", {k: trainer.run.best[k] for k in ("update", "global_step", "score", "greedy")})
print("run folder:", sorted(p.name for p in run_dir.iterdir()))

# %% [markdown]
# ## The learning curve
#
# Two sources. The run's `history` (`trainer.run.history`) holds each score on the public seeds; the
# TensorBoard scalars in `RUN/tb` hold, among others, the NSW of every finished training
# episode (`episode/nsw`), read here with TensorBoard's `EventAccumulator`
# (`tensorboard --logdir RUN/tb` shows them all in a browser). The dashed line is the
# heuristic on the same public seeds.

# %%
scalars = EventAccumulator(str(run_dir / "tb"))
scalars.Reload()
print("scalars:", sorted(scalars.Tags()["scalars"]))
episodes = scalars.Scalars("episode/nsw")
public = trainer.run.history
heuristic_public = wfbench.evaluate("heuristic", "small", seeds=public[0]["seeds"])["nsw"].mean()

fig, ax = plt.subplots(figsize=(10, 4))
episode_nsw = pd.Series([e.value for e in episodes], index=[e.step for e in episodes])
ax.scatter(episode_nsw.index, episode_nsw, s=6, alpha=0.4, color="gray", label="training episodes (train seeds)")
ax.plot(episode_nsw.rolling(20, min_periods=1).mean(), color="gray", label="their mean over 20 episodes")
ax.plot([h["global_step"] for h in public], [h["sample"] for h in public], "o-", label="public seeds, sampled")
ax.plot([h["global_step"] for h in public], [h["greedy"] for h in public], "s--", label="public seeds, greedy")
ax.axhline(heuristic_public, color="black", ls=":", label="heuristic, public seeds")
ax.set_xlabel("environment steps")
ax.set_ylabel("episode NSW")
ax.set_title(f"PPO on small, cpu network, {trainer.run.global_step} steps in {minutes:.1f} min")
ax.legend(loc="lower right", fontsize=8)
fig.tight_layout()
plt.show()

# %% [markdown]
# ## The checkpoint is a policy
#
# `ppo:PATH` loads a checkpoint wherever a policy name is accepted: `policies.get`,
# `wfbench.evaluate`, `compare`, the command line, the leaderboard. Decisions are
# sampled by default (`ppo:PATH@greedy` for argmax), with one random generator per
# environment keyed by its seed, so a seed decides the same alone or in any batch. The
# final numbers are on the test seeds, which played no part in training or selection.

# %%
checkpoint = f"ppo:{run_dir / 'best.pt'}"
learned = policies.get(checkpoint)
print(learned)
table = compare([checkpoint, "heuristic", "random"], "small", seeds=SEEDS, baseline="heuristic")
print(format_comparison(table))
assert table["nsw"].notna().all() and len(table.attrs["runs"][checkpoint]) == SEEDS

# %% [markdown]
# ## The same run from the command line, and on a GPU
#
# The cell above is this command:
#
# ```bash
# wfbench train --algo ppo --variant joint --scenario small --model cpu --device cpu \
#     --steps 65536 --num-envs 16 --num-steps 32 --epochs 2 --minibatches 2 \
#     --eval-every 16 --eval-seeds public:4 --seed 0 --run-dir runs/ppo-small
# wfbench evaluate --policy ppo:runs/ppo-small/best.pt --scenario small --seeds test
# ```
#
# On a machine with a CUDA GPU (and a CUDA build of torch: the `rl` extra pins the CPU
# build), the same command with `--device cuda` runs the forward passes under bf16
# autocast; `--compile` adds `torch.compile`, and a GPU pays off with the paper-size
# network and many environments side by side:
#
# ```bash
# wfbench train --algo ppo --variant joint --scenario paper-64 --model paper --device cuda --compile \
#     --num-envs 1024 --num-steps 64 --epochs 3 --minibatches 4 --steps 20000000 --run-dir runs/joint-gpu
# ```
#
# In Python: `TrainConfig(..., model="paper", device="cuda", compile=True, num_envs=1024)`.
# The checkpoint it writes evaluates on the CPU like any other (`ppo:runs/joint-gpu/best.pt`).
# No GPU was used to write this notebook; the GPU settings are those of
# [PPO and `wfbench train`](../../rl/#the-command-line).
