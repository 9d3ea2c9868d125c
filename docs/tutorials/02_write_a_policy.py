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
# # Write your own policy
#
# A policy is a class with `decisions`, `reset(seeds)` and `act(obs)`; nothing needs to
# be inherited ([Writing a policy](../../policies/) is the whole contract). This
# notebook writes one, compares it with the heuristic on the same seeds, runs it on the
# three backends (this process, a process pool, Ray), submits it to a leaderboard in a
# scratch folder and writes the leaderboard's HTML page. It runs on the `small`
# scenario in under a minute on two idle cores, most of it starting processes: a
# process pool, Ray, and the leaderboard's child process for each submission.
#
# Source: [02_write_a_policy.py](02_write_a_policy.py), a jupytext file
# ([how to open it](../01_evaluate_and_compare/)).

# %%
import os
import tempfile
from pathlib import Path

import numpy as np

import wfbench
from wfbench import policies
from wfbench.harness.compare import compare, format_comparison

QUICK = os.environ.get("WFBENCH_TUTORIAL_QUICK") == "1"  # set by the test suite: fewer seeds
SCENARIO = "small"
SEEDS = 10 if QUICK else 50  # the first N test seeds, 0..N-1
workdir = Path(tempfile.mkdtemp(prefix="wfbench-tutorial-"))  # everything this notebook writes goes here
print(workdir)

# %% [markdown]
# ## The policy
#
# A dispatch rule: serve the open requests longest-down first (by each facility's
# rolling downtime, the `downtime` column of the facility features), each with the
# nearest free person (Manhattan distance from where they are now). Workforce and
# positioning stay the paper's heuristics, so the comparison with the heuristic isolates
# the dispatch rule.
#
# The leaderboard and the command line name a policy as `module:attr` and run it in a
# fresh process that cannot see this notebook, so the policy is a module: the cell below
# holds its source and writes it to `my_policy.py` in the scratch folder, and the cell
# after runs the same source here (`exec`), which defines the class in this notebook as if
# its code had been typed into a cell. Plain Python, so this file runs the same as a
# notebook and as a script (`python 02_write_a_policy.py`); in Jupyter, `%%writefile`
# and `%run` would do the same.

# %%
POLICY_SOURCE = '''\
import numpy as np

from wfbench import policies
from wfbench.core.observe import FAC_DOWNTIME, FAC_X, FAC_Y, PER_X, PER_Y


class LongestDownFirst:
    """Open requests by rolling downtime, longest first; each gets the nearest free person."""

    decisions = ("dispatch",)
    name = "longest-down-first"

    def reset(self, seeds):
        pass  # no memory and no random numbers: nothing to forget between batches

    def act(self, obs):
        B, M = obs["requesting"].shape
        N = obs["personnel"].shape[1]
        dispatch = np.full((B, M), N, dtype=np.int64)  # N: nobody is sent
        for b in range(B):
            free = obs["dispatchable"][b].astype(bool)  # a copy: the observation stays untouched
            open_requests = np.flatnonzero(obs["requesting"][b])
            downtime = obs["facilities"][b, open_requests, FAC_DOWNTIME]
            for f in open_requests[np.argsort(-downtime, kind="stable")]:
                if not free.any():
                    break
                fac = obs["facilities"][b, f]
                people = obs["personnel"][b]
                distance = np.abs(people[:, PER_X] - fac[FAC_X]) + np.abs(people[:, PER_Y] - fac[FAC_Y])
                p = int(np.argmin(np.where(free, distance, np.inf)))
                dispatch[b, f] = p
                free[p] = False
        return {"dispatch": dispatch}


def make_policy():
    """The whole policy: our dispatch with the paper's workforce and positioning heuristics."""
    return policies.Composite(dispatch=LongestDownFirst(), workforce="threshold", positioning="spatial")
'''
policy_file = workdir / "my_policy.py"
policy_file.write_text(POLICY_SOURCE)
print("wrote", policy_file)

# %%
# the module's code run here, its classes in __main__ as if typed into a cell (so pickled by value)
here = {"__name__": "__main__"}
exec(compile(POLICY_SOURCE, str(policy_file), "exec"), here)
LongestDownFirst, make_policy = here["LongestDownFirst"], here["make_policy"]

mine = make_policy()
assert isinstance(mine, policies.Policy)  # the protocol, checked at run time
print(mine, "| the class lives in", LongestDownFirst.__module__)

# %% [markdown]
# ## Compared with the heuristic
#
# The heuristic is `nearest+threshold+spatial`: the same composite with nearest-first
# dispatch. Same seeds, so the difference is paired by seed.

# %%
table = compare([mine, "heuristic"], SCENARIO, seeds=SEEDS, baseline="heuristic")
print(format_comparison(table))
runs = table.attrs["runs"]
assert (runs[mine.name]["invalid_actions"] == 0).all()  # only free people, only open requests, nobody twice

# %% [markdown]
# ## Every backend
#
# `wfbench.evaluate(..., execution=wfbench.Execution(backend=...))` runs the same
# episodes in this process (`serial`), in a pool of worker processes (`process`) or as Ray tasks (`ray`). A seed
# gives the same numbers on all three, which the next cells check. What travels to the
# workers is the policy object, pickled by cloudpickle:
#
# - a class defined in the notebook (here, through `exec`) lives in `__main__`, and
#   cloudpickle sends it **by value**: its code goes with the object, and the workers
#   need nothing installed but wfbench. Both `process` and `ray` run it, also on a
#   Ray cluster (`Execution(backend="ray", address=...)`);
# - a class **imported** from a module (`from my_policy import LongestDownFirst`) goes
#   **by reference**: each worker imports the module itself. The `process` workers get
#   this notebook's folder and `sys.path`, so they find the module wherever this
#   notebook does. Ray's local workers find a module in the notebook's folder, but not
#   one in a folder added to `sys.path` (they fail with `No module named 'my_policy'`),
#   and the nodes of a cluster only what is installed on them;
#   `ray.init(runtime_env={"py_modules": [my_policy]})` ships the module to the workers
#   (checked with Ray 2.60).
#
# Ray is started here with its log quieted; without this call `wfbench.evaluate` starts
# a local Ray instance itself, and `address="auto"` (or `"ray://host:10001"`) in the
# `Execution` joins an existing cluster.

# The frames carry, beside the results, what each run cost (`decision_ms_p50`,
# `decision_ms_p99`, `cpu_s`): measurements of this machine at this moment, which differ
# from run to run. `wfbench.harness.budget.results_only` drops them, and what is left must agree
# to the bit on every backend.

# %%
import ray

from wfbench.harness.budget import results_only

ray.init(num_cpus=os.cpu_count(), include_dashboard=False, logging_level="ERROR", log_to_driver=False)

by_backend = {"serial": runs[mine.name]}  # compare ran it in this process above
for backend in ("process", "ray"):
    by_backend[backend] = wfbench.evaluate(mine, SCENARIO, seeds=SEEDS, execution=wfbench.Execution(backend=backend))
for backend, df in by_backend.items():
    print(f"{backend:8s} mean NSW {df['nsw'].mean():.6f}")
    assert results_only(df).equals(results_only(by_backend["serial"])), f"{backend} differs from serial"
ray.shutdown()

# %% [markdown]
# ## On a leaderboard
#
# A leaderboard is a track (a scenario and its seed lists) and a store (one SQLite
# file). The built-in tracks are `paper-64`, `nonstationary` and `large`
# ([Leaderboard](../../leaderboard/)); for a quick run this notebook defines a track on
# `small` with the first test seeds, and keeps the store in the scratch folder.
# `submit` takes the policy as a string, a registry name or `module:attr` (a class or a
# factory), and runs it in a fresh child process, so the folder of `my_policy.py` goes
# on `sys.path` (the child gets this process's path).

# %%
import sys

from wfbench.leaderboard.report import ranking, render, render_html
from wfbench.leaderboard.store import Store
from wfbench.leaderboard.submit import submit
from wfbench.leaderboard.tracks import scenario_track

sys.path.insert(0, str(workdir))
track = scenario_track(name="small-tutorial", config=wfbench.ScenarioConfig.preset(SCENARIO),
                       public_seeds=tuple(range(1000, 1010)), test_seeds=tuple(range(SEEDS)),
                       description="the small scenario, for the tutorial")
store = Store(workdir / "leaderboard.sqlite")
for policy, name in (("heuristic", "heuristic"), ("my_policy:make_policy", "longest-down-first")):
    outcome = submit(track, policy, name, submitter="tutorial", db=store, execution=wfbench.Execution(backend="serial"))
    print(f"{name}: {outcome.status} {outcome.reason}, {outcome.stored_rows} seeds stored in {outcome.seconds:.1f} s")
    assert outcome.status == "complete", outcome.reason

# %% [markdown]
# The ranking, as text, and the same rows from the store: the leaderboard's numbers are
# those of `wfbench.evaluate` on the same seeds.

# %%
board = ranking(store, track, baseline="heuristic")
print(render(board))
stored = board.per_seed[board.per_seed["name"] == "longest-down-first"].sort_values("seed")
assert np.allclose(stored["nsw"].to_numpy(), runs[mine.name]["nsw"].to_numpy()[: len(track.test_seeds)])

# %% [markdown]
# ## The HTML page
#
# `render_html` makes one self-contained page: the ranking, the NSW with its intervals
# and the per-seed KPIs as embedded pictures. Write it to a file and open it in a
# browser; from Python, `webbrowser.open(page.as_uri())` does that. The same page from
# the command line, for a built-in track:
# `wfbench leaderboard show --track paper-64 --format html --out board.html`.
# Below, the page shown inside the notebook.

# %%
import html

from IPython.display import HTML, display

page = workdir / "leaderboard.html"
page.write_text(render_html(board))
text = page.read_text()
assert "<table id='ranking'>" in text and "longest-down-first" in text and "data:image/png;base64," in text
print(f"{page}, {page.stat().st_size / 1024:.0f} kB")
print(f"to open it: import webbrowser; webbrowser.open({page.as_uri()!r})")
# an iframe keeps the page's own styles apart from the notebook's
display(HTML(f'<div><iframe srcdoc="{html.escape(text)}" style="width: 100%; height: 640px; border: 1px solid #ccc">'
             "</iframe></div>"))

# %% [markdown]
# The scratch folder is left in place (its path is printed at the top) so that the page
# and the store can be opened after the notebook ends. On a real track:
#
# ```bash
# wfbench leaderboard submit --policy my_policy:make_policy --name mine --track paper-64
# wfbench leaderboard show --track paper-64 --format html --out board.html
# ```
#
# run from the folder that holds `my_policy.py`.
