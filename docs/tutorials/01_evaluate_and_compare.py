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
# # Evaluate and compare the built-in policies
#
# This notebook scores the built-in policies on the same seeds, reads the paired
# differences to the heuristic with their 95% intervals, and plots the KPIs over the
# episode. It runs on the `small` scenario (a 16x16 grid, 8 facility and 8 personnel
# slots, 200 steps), so it finishes in well under a minute on two cores (35 s as a script
# on the 2-core VM, 2026-11-28, beside two other jobs, the numba cache warm; a fresh
# install first compiles the numba core once, about 75 s on an idle 2-core VM); every
# call takes `"paper-64"` (the paper's setting) as well.
#
# Every tutorial is a plain Python file in the
# [jupytext](https://jupytext.readthedocs.io) percent format, this one
# [01_evaluate_and_compare.py](01_evaluate_and_compare.py) in `docs/tutorials/`.
# JupyterLab with jupytext installed opens it as a notebook, and
# `jupytext --to ipynb 01_evaluate_and_compare.py` converts it (jupytext comes with the
# `docs` extra). The test suite runs all of them (`tests/contracts/test_tutorials.py`), so what
# they show stays true.

# %%
import os

import matplotlib.pyplot as plt
import numpy as np

import wfbench
from wfbench.core.state import METRICS  # the names of the last axis of the per-step series
from wfbench.harness.compare import compare, format_comparison

QUICK = os.environ.get("WFBENCH_TUTORIAL_QUICK") == "1"  # set by the test suite: fewer seeds
SCENARIO = "small"
SEEDS = 20 if QUICK else 50  # the first N test seeds, 0..N-1; 50 is the whole test set, what tables report
POLICIES = ["random", "heuristic", "solver", "heuristic-tuned", "oracle"]

# %% [markdown]
# ## The comparison
#
# `compare` evaluates every policy on the same seeds. A seed fixes every exogenous
# event (failures, facility arrivals and departures, repair luck), so each seed is the
# same world for every policy and the difference to the baseline is *paired* by seed:
# the variance between worlds drops out. The policies:
#
# - `random`: random decisions, the paper's lower reference;
# - `heuristic`: the paper's heuristics (nearest dispatch, utilization thresholds for
#   hiring and letting go, positioning by a demand heat map);
# - `solver`: the operations-research composite (assignment dispatch, square-root
#   staffing, p-median positioning; [Solvers](../../solvers/));
# - `heuristic-tuned`: the heuristic with its parameters tuned on `paper-64`'s public
#   seeds, run here unchanged on `small`;
# - `oracle`: a hindsight oracle that reads the episode's future, a reference for what
#   a deployable policy leaves on the table ([Oracles and the bound](../../hindsight/)).

# %%
table = compare(POLICIES, SCENARIO, seeds=SEEDS, baseline="heuristic")
print(format_comparison(table))

# %% [markdown]
# Each KPI is `mean (25%-75%)` over the seeds of the episode means. The score is the
# Nash social welfare (NSW, higher is better; [Metrics](../../metrics/)). The last two
# columns are the paired difference to the heuristic with its bootstrap 95% interval
# (seeds resampled together) and the number of seeds on which the policy beats it.
#
# The same numbers are in the DataFrame `compare` returns, one row per policy, and the
# per-seed rows of every policy are in `table.attrs["runs"]`:

# %%
table[["policy", "nsw", "nsw_ci_low", "nsw_ci_high", "nsw_diff", "nsw_diff_low", "nsw_diff_high", "wins"]].round(4)

# %%
runs = table.attrs["runs"]  # policy name -> its per-seed DataFrame
base = runs["heuristic"]["nsw"].to_numpy()
for name in POLICIES:
    row = table.set_index("policy").loc[name]
    diff = runs[name]["nsw"].to_numpy() - base
    # the table's difference is the mean of the per-seed differences, inside its own interval
    assert np.isclose(row["nsw_diff"], diff.mean())
    assert row["nsw_diff_low"] <= row["nsw_diff"] <= row["nsw_diff_high"]
# facts this page relies on: the oracle (which reads the future) beats the heuristic, random loses to it
assert table.set_index("policy").loc["oracle", "nsw_diff_low"] > 0
assert table.set_index("policy").loc["random", "nsw_diff_high"] < 0

# %% [markdown]
# ## The paired differences as a picture
#
# Left: each policy's NSW on every seed (one dot per seed) and its mean. Right: the
# paired difference to the heuristic per seed, its mean and 95% interval. An interval
# that excludes zero is a difference the seeds support.

# %%
others = [p for p in POLICIES if p != "heuristic"]
rng = np.random.default_rng(0)  # horizontal jitter of the dots only
fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4))
for i, name in enumerate(POLICIES):
    nsw = runs[name]["nsw"].to_numpy()
    left.scatter(i + rng.uniform(-0.15, 0.15, nsw.size), nsw, s=8, alpha=0.5)
    left.hlines(nsw.mean(), i - 0.3, i + 0.3, color="black")
left.set_xticks(range(len(POLICIES)), POLICIES, rotation=20)
left.set_ylabel("episode NSW (higher is better)")
left.set_title(f"NSW per seed on {SCENARIO}, {len(base)} seeds")

rows = table.set_index("policy").loc[others]
for i, name in enumerate(others):
    diff = runs[name]["nsw"].to_numpy() - base
    right.scatter(diff, i + rng.uniform(-0.15, 0.15, diff.size), s=8, alpha=0.4)
mean = rows["nsw_diff"].to_numpy()
err = np.vstack([mean - rows["nsw_diff_low"].to_numpy(), rows["nsw_diff_high"].to_numpy() - mean])
right.errorbar(mean, range(len(others)), xerr=err, fmt="o", color="black", capsize=5, label="mean, 95% CI")
right.axvline(0, color="gray", lw=1)
right.set_yticks(range(len(others)), others)
right.set_xlabel("NSW minus the heuristic's on the same seed")
right.set_title("Paired differences to the heuristic")
right.legend(loc="lower right")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## The KPIs over the episode
#
# `wfbench.evaluate(..., return_series=True)` also returns the per-step metrics, an
# array of shape (seeds, steps, metrics) whose last axis follows `wfbench.core.state.METRICS`.
# An episode's score is the mean of its per-step NSW, which the next cell checks.

# %%
print(METRICS)
shown = ["random", "heuristic", "solver", "oracle"]
series = {}
for name in shown:
    df, series[name] = wfbench.evaluate(name, SCENARIO, seeds=SEEDS, return_series=True)
    nsw_steps = series[name][:, :, METRICS.index("nsw")]
    assert np.allclose(nsw_steps.mean(axis=1), df["nsw"], atol=1e-5)
print({name: s.shape for name, s in series.items()})

# %% [markdown]
# The mean over the seeds at each step, with the 25%-75% band. The gray band in the
# utilization panel is the paper's target, 0.75 +- 0.05.

# %%
panels = [("workforce_cost", "Workforce cost (salaries)"), ("utilization", "Personnel utilization rate"),
          ("downtime", "Facility downtime"), ("nsw", "Nash social welfare")]
fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
for ax, (metric, label) in zip(axes.flat, panels, strict=True):
    for name in shown:
        values = series[name][:, :, METRICS.index(metric)]
        steps = np.arange(values.shape[1])
        line, = ax.plot(steps, values.mean(axis=0), label=name)
        q25, q75 = np.quantile(values, [0.25, 0.75], axis=0)
        ax.fill_between(steps, q25, q75, color=line.get_color(), alpha=0.15, lw=0)
    if metric == "utilization":
        ax.axhspan(0.70, 0.80, color="0.85", zorder=0)
    ax.set_title(label)
for ax in axes[1]:
    ax.set_xlabel("step")
axes[0, 0].legend()
fig.suptitle(f"KPIs over the episode on {SCENARIO}: mean and 25%-75% over {len(base)} seeds")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## One world, every policy
#
# The trace of a seed (`wfbench.core.trace`) holds every exogenous draw of its episode, and
# none of them depends on a decision. Below, seed 0: the headcount each policy keeps,
# with the facility arrivals of the trace, which are the same for all of them.

# %%
config = wfbench.ScenarioConfig.preset(SCENARIO)
world = wfbench.trace(config, 0)
arrivals = world.arr_t[0]
print(f"seed 0: {int(world.fac0_active.sum())} facilities and {int(world.per0_active.sum())} people at the start, "
      f"{arrivals.size} facility arrivals at steps {arrivals.tolist()}")

fig, ax = plt.subplots(figsize=(12, 3.5))
for name in shown:
    ax.step(np.arange(config.horizon), series[name][0, :, METRICS.index("headcount")], where="post", label=name)
for t in arrivals:
    ax.axvline(t, color="gray", lw=0.8, ls=":")
ax.set_xlabel("step (dotted: a facility arrives)")
ax.set_ylabel("people employed")
ax.set_title("Seed 0: the same arrivals for every policy, different workforce decisions")
ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1))
fig.tight_layout()
plt.show()

# %% [markdown]
# ## From the command line
#
# The same comparison, printed as the table above:
#
# ```bash
# wfbench compare --policies random,heuristic,solver,heuristic-tuned,oracle --baseline heuristic \
#     --scenario small --seeds test
# ```
#
# Next: [write your own policy](../02_write_a_policy/) and put it on the leaderboard.
