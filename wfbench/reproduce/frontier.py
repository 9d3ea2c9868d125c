"""The verdict as score against compute: held-out IQM per policy beside what its decisions cost (issue #43).

``wfbench reproduce frontier`` reads a suite run's pieces (``out/cache``, then the ``reuse``
folders; a piece with more seeds is cut to the chosen ones, one with fewer is extended by only
the seeds it lacks: :mod:`wfbench.reproduce.pieces`) and plays what is missing, after saying
what that is and about how long it takes. It writes, per policy, the IQM of the normalized
score with its interval beside the decision time p50, CPU ms per env-step and CPU s per
episode, the figure (each family's Pareto front against CPU ms per env-step), and the best
deployable policy of the OR and learned sides within each budget of :data:`BUDGETS_MS`.
Without options it reproduces the committed frontier (:data:`COMMITTED`, its
``frontier-run.json``) from the committed pieces. docs/suite.md, "Score against compute",
explains the columns and holds the committed run.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.analysis.aggregate import AGGREGATE_NOTE, aggregate_suite
from wfbench.analysis.tables import markdown_table
from wfbench.core.kpis import SCORE
from wfbench.core.seeds import describe, resolve_seeds
from wfbench.harness.backends import Execution
from wfbench.reproduce import pieces, provenance
from wfbench.reproduce.common import PROCESS, Output, Progress, checkout_root, write
from wfbench.reproduce.suite import family as suite_family
from wfbench.scenarios import SuiteScenario, get_suite, normalize

BUDGETS_MS = (1.0, 10.0, 100.0)  # CPU ms per env-step: the "about 1 ms, 10 ms, 100 ms"
BASELINE = "solver-tuned"  # the probability of improvement is taken over it (the rollouts' base)
SIDES = {"heuristic": "OR", "solver": "OR", "rollout": "OR", "mpc": "OR", "network": "learned", "search": "learned",
         "oracle": "reference", "random": "reference"}
COMMITTED = "docs/results/frontier-v1"  # the committed frontier: its pieces and its settings (frontier-run.json)
# the committed runs, relative to the checkout's root: the suite's, then the held-out reference's (its candidates'
# pieces: the lookaheads' other presets, docs/hindsight.md "The held-out reference")
DEFAULT_REUSE = (COMMITTED, "docs/results/suite-v1-50", "docs/results/reference-v2")


def stem(split: str) -> str:
    """The name a frontier's files start with: ``frontier`` for the held-out split (the verdict), else split's."""
    return "frontier" if split == "heldout" else f"frontier-{split}"


def default_reuse() -> tuple[Path, ...]:
    """The committed runs' folders, found from the checkout whatever the current folder (none when installed)."""
    root = checkout_root()
    return () if root is None else tuple(root / r for r in DEFAULT_REUSE)


def committed_settings(split: str = "heldout") -> dict | None:
    """The settings of the committed frontier of ``split`` (``frontier-run.json``), or None where there is none."""
    root = checkout_root()
    path = None if root is None else root / COMMITTED / f"{stem(split)}-run.json"  # what it was drawn from
    return json.loads(path.read_text()) if path is not None and path.exists() else None


def default_policies() -> list[str]:
    """The heuristics and solvers (tuned too), every deployable lookahead, the scale-free network, the oracle."""
    from wfbench.policies.registry import lookahead_names

    return ["heuristic", "heuristic-tuned", "heuristic-tuned-train", "solver", "solver-tuned", "solver-tuned-train",
            *lookahead_names(), "ppo-general", "scalefree-general", "oracle"]


def family(policy: str) -> str:
    """The line a policy is joined on: rollout, mpc, search (the network's own), or the suite's family."""
    if policy.startswith(("search-", "switch-")):  # issue #52: the learned side's lookaheads
        return "search"
    if policy.startswith("rollout-"):
        return "rollout"
    if policy.startswith("mpc"):
        return "mpc"
    return suite_family(policy)


def size(policies: Sequence[str] | None = None, scenarios: Sequence[str] | None = None, split: str = "heldout",
         suite_name: str = "suite-v1", **_: object) -> int:
    """The (policy, scenario) pieces :func:`frontier` reads or plays (for a progress bar)."""
    settings = committed_settings(split) or {}
    policies = policies or settings.get("policies") or default_policies()
    scenarios = scenarios or settings.get("scenarios")
    return len(policies) * len(_chosen(get_suite(suite_name), scenarios, split))


def _chosen(suite, scenarios: Sequence[str] | None, split: str) -> list[SuiteScenario]:
    if scenarios:
        chosen = [suite.scenario(x) for x in scenarios]
        wrong = [sc.id for sc in chosen if sc.split != split]
        if wrong:
            raise ValueError(f"scenario {wrong[0]} is in the {suite.scenario(wrong[0]).split} split, not {split}; "
                             f"allowed: the {split} scenarios of {suite.name}")
        return chosen
    return [sc for sc in suite.scenarios if sc.split == split]


def cost_row(df: pd.DataFrame) -> dict[str, float]:
    """What a policy's pieces cost: decision p50 (median over episodes), CPU ms per env-step, CPU s per episode."""
    steps = float(df["episode_length"].sum())
    return {"decision_ms_p50": float(df["decision_ms_p50"].median()),
            "cpu_ms_per_step": 1e3 * float(df["cpu_s"].sum()) / steps,
            "cpu_s_per_episode": float(df["cpu_s"].mean())}


def verdicts(table: pd.DataFrame, budgets: Sequence[float] = BUDGETS_MS) -> list[dict]:
    """At each budget: the best OR and the best learned policy within it (by IQM), and who is ahead.

    Within a budget means a CPU cost per env-step (``cpu_ms_per_step``) at most the budget.
    "apart" when their 95% IQM intervals do not overlap.
    """
    out = []
    for b in budgets:
        within = table[table["cpu_ms_per_step"] <= b]
        best = {}
        for side in ("OR", "learned"):
            s = within[within["side"] == side]
            best[side] = s.loc[s["iqm"].idxmax()] if len(s) else None
        row = {"budget_ms": b}
        for side, r in best.items():
            row[f"{side}_policy"] = None if r is None else r["policy"]
            row[f"{side}_iqm"] = np.nan if r is None else r["iqm"]
        o, n = best["OR"], best["learned"]
        if o is None or n is None:  # one side alone is ahead, with no interval to compare
            row["apart"] = None
            row["ahead"] = "OR" if o is not None else "learned" if n is not None else None
        else:
            hi, lo = (o, n) if o["iqm"] >= n["iqm"] else (n, o)
            row["ahead"] = "OR" if hi is o else "learned"
            row["apart"] = bool(hi["iqm_low"] > lo["iqm_high"])
        out.append(row)
    return out


def frontier(out: Path, runs: int | None = None, execution: Execution = PROCESS, progress: Progress = None,
             seeds: str | Sequence[int] | None = None, policies: Sequence[str] | None = None,
             scenarios: Sequence[str] | None = None, split: str = "heldout",
             reuse: Sequence[str | Path] | None = None, suite_name: str = "suite-v1", reps: int = 5000,
             poi_reps: int = 1000, announce: Callable[[str], None] | None = None, plan_only: bool = False,
             classes: Path | None = None, **_: object) -> Output:
    """Held-out IQM against decision cost per policy, the figure, and the verdict at each budget (module docstring).

    Args:
        out: the output folder (pieces played here are kept in its ``cache/``).
        runs: seeds 0..runs-1 when ``seeds`` is not given.
        execution: how missing pieces are played (:class:`~wfbench.harness.backends.Execution`).
        progress: called with the name of each piece as it is read or played.
        seeds: the seeds (a set name or a list). Seeds, policies and scenarios not given are the
            committed frontier's (:func:`committed_settings`), else test seeds 0-49,
            :func:`default_policies` and the split's scenarios.
        policies: the policies.
        scenarios: a subset of the split's scenarios.
        split: ``heldout`` (default) or ``train``.
        reuse: suite run folders whose ``cache/`` pieces are read before anything is played
            (default :func:`default_reuse`, the committed runs).
        suite_name: the suite.
        reps: bootstrap replications of the intervals.
        poi_reps: bootstrap replications of the probability of improvement's interval.
        announce: called once with what will be played and its estimated CPU time
            (:func:`wfbench.reproduce.pieces.describe_plan`) before anything is played.
        plan_only: stop after announcing the plan (``files`` empty; the text is the plan).
        classes: also write each policy's CPU ms per env-step there (:func:`write_classes`; the
            committed frontier's is ``policies/budgets.json``, what ``wfbench policies`` reads).
    """
    s = get_suite(suite_name)
    settings = committed_settings(split) or {}
    chosen = _chosen(s, scenarios or settings.get("scenarios"), split)
    if seeds is not None:
        seed_list = resolve_seeds(seeds)
    elif runs is not None:
        seed_list = list(range(runs))
    else:
        seed_list = [int(x) for x in settings.get("seeds", range(50))]
    names = list(dict.fromkeys(policies or settings.get("policies") or default_policies()))
    folders = [Path(out), *(Path(r) for r in (default_reuse() if reuse is None else reuse))]
    provenance.start()  # the code this run starts with is the code its pieces record
    todo = pieces.plan(folders, names, chosen, seed_list, others=s.scenarios)
    text = pieces.describe_plan(todo, execution.workers or os.cpu_count() or 1)
    if announce:
        announce(text)
    if plan_only:
        return Output(text, [])
    frames: dict[str, pd.DataFrame] = {}
    failures = []
    for name in names:
        parts = []
        for sc in chosen:
            if progress:
                progress(f"{sc.id}: {name}")
            try:
                df = pieces.obtain(folders, out, name, sc, seed_list, execution)
            except Exception as exc:  # noqa: BLE001 - a long run reports a failing piece and goes on
                failures.append([sc.id, name, f"{type(exc).__name__}: {exc}".splitlines()[0]])
                continue
            df = df.copy()
            df.insert(0, "normalized", normalize(df[SCORE].to_numpy(), sc.id, s))
            df.insert(0, "split", sc.split)
            df.insert(0, "scenario", sc.id)
            parts.append(df)
        if len(parts) == len(chosen):
            frames[name] = pd.concat(parts, ignore_index=True)
    if not frames:
        raise ValueError("no policy has a result on every chosen scenario: " + "; ".join(" ".join(f) for f in failures))
    baseline = BASELINE if BASELINE in frames else None
    agg = aggregate_suite(frames, baseline=baseline, reps=reps, poi_reps=poi_reps)[split]
    table = agg.table.set_index("policy")
    rows = []
    for name, df in frames.items():
        fam = family(name)
        r = table.loc[name]
        rows.append({"policy": name, "family": fam, "side": SIDES.get(fam, "other"),
                     "iqm": r["iqm"], "iqm_low": r["iqm_low"], "iqm_high": r["iqm_high"],
                     "p_improve": r.get("p_improve", np.nan), "p_improve_low": r.get("p_improve_low", np.nan),
                     "p_improve_high": r.get("p_improve_high", np.nan), **cost_row(df)})
    result = pd.DataFrame(rows)
    files: list[Path] = []
    seeds_text = describe(seed_list)
    ids = ", ".join(sc.id for sc in chosen)
    header = ["Policy", "Family", "IQM [95% CI]", f"P(improvement over {baseline}) [95% CI]",
              "Decision p50 (ms)", "CPU ms / env-step", "CPU s / episode"]
    cells = [[r["policy"], r["family"], f"{r['iqm']:.3f} [{r['iqm_low']:.3f}, {r['iqm_high']:.3f}]",
              "(baseline)" if r["policy"] == baseline or np.isnan(r["p_improve"]) else
              f"{r['p_improve']:.2f} [{r['p_improve_low']:.2f}, {r['p_improve_high']:.2f}]",
              f"{r['decision_ms_p50']:.3g}", f"{r['cpu_ms_per_step']:.3g}", f"{r['cpu_s_per_episode']:.3g}"]
             for _, r in result.sort_values("cpu_ms_per_step").iterrows()]
    v = verdicts(result)
    verdict_rows = [[f"<= {x['budget_ms']:g} ms", _side_cell(x, "OR"), _side_cell(x, "learned"), _ahead_cell(x)]
                    for x in v]
    md = "\n".join([
        f"{s.name}, {split} split ({len(chosen)} scenarios: {ids}), seeds {seeds_text}: IQM of the normalized score "
        "per policy beside what it cost, cheapest first. Decision p50: the evaluator's median decision time (for a "
        "compiled composite its whole rollout per env-step); CPU ms / env-step: the CPU seconds of the episodes over "
        "their env-steps (observe, decide and simulate), the cost the budgets below are measured in.", "",
        markdown_table(header, cells), "", AGGREGATE_NOTE, "",
        "The best deployable policy of each side within each budget (CPU ms per env-step; the oracle reads the "
        "future and is not deployable):", "",
        markdown_table(["Budget", "Best OR (IQM)", "Best learned (IQM)", "Ahead"], verdict_rows)])
    if "oracle" in frames:
        md += "\n\n" + _oracle_line(frames)
    if failures:
        md += "\n\nFailed (not cached; a rerun tries them again):\n\n" + markdown_table(["Scenario", "Policy", "Error"],
                                                                                        failures)
    name = stem(split)
    files += write(out, name, md, result)
    (out / f"{name}-verdict.csv").write_text(pd.DataFrame(v).to_csv(index=False))
    run = {"suite": s.name, "split": split, "seeds": seed_list, "scenarios": [sc.id for sc in chosen],
           "policies": list(frames)}  # what it was drawn from: the defaults of the next run without options
    (out / f"{name}-run.json").write_text(json.dumps(run, indent=1) + "\n")
    files += [out / f"{name}-verdict.csv", out / f"{name}-run.json"]
    files += _figure(result, split, len(chosen), seeds_text, out / name)
    if classes is not None:
        files.append(write_classes(result, Path(classes), run))
    return Output(md, files)


def write_classes(result: pd.DataFrame, path: Path, run: dict) -> Path:
    """Write each policy's measured CPU ms per env-step (``result``'s) and what it was measured on to ``path``.

    This is the data :attr:`wfbench.policies.table.Entry.budget` reads: a measurement is data,
    so that drawing the frontier again edits no source file (whose bytes decide what the
    replaying oracle may reuse, ``wfbench.policies.oracle.pieces``).
    """
    data = {"about": "CPU ms per env-step of each policy as wfbench reproduce frontier measured it; wfbench "
                     "policies prints its budget class from here (docs/policies.md, \"Listing policies\")",
            "measured_on": {"suite": run["suite"], "split": run["split"], "scenarios": run["scenarios"],
                            "seeds": describe(run["seeds"])},
            "cpu_ms_per_step": {r["policy"]: float(r["cpu_ms_per_step"]) for _, r in result.iterrows()}}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


def _oracle_line(frames: dict[str, pd.DataFrame]) -> str:
    """Whether the oracle's mean NSW is at least every other policy's on every scenario, and where not."""
    means = {n: df.groupby("scenario", sort=False)[SCORE].mean() for n, df in frames.items()}
    oracle = means.pop("oracle")
    above = [f"{n} on {sc} ({m[sc]:.4f} > {oracle[sc]:.4f})" for n, m in means.items() for sc in m.index
             if m[sc] > oracle[sc]]
    if not above:
        return (f"The oracle's mean NSW is at least every other policy's here on each of the {len(oracle)} "
                "scenarios.")
    return "The oracle's mean NSW is below: " + "; ".join(above) + "."


def _ahead_cell(v: dict) -> str:
    if v["ahead"] is None:
        return "-"
    return v["ahead"] + ("" if v["apart"] is None else ", intervals apart" if v["apart"] else ", intervals overlap")


def _side_cell(v: dict, side: str) -> str:
    return "-" if v[f"{side}_policy"] is None else f"{v[f'{side}_policy']} ({v[f'{side}_iqm']:.3f})"


def pareto(costs: Sequence[float], scores: Sequence[float]) -> list[int]:
    """The indices on the Pareto front, cheapest first: each scores more than every cheaper point (ties: cheaper)."""
    order = sorted(range(len(costs)), key=lambda i: (costs[i], -scores[i]))
    front, best = [], -np.inf
    for i in order:
        if scores[i] > best:
            front.append(i)
            best = scores[i]
    return front


def _figure(result: pd.DataFrame, split: str, n: int, seeds_text: str, path_stem: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.analysis.plots import save_figure

    fig, ax = plt.subplots(figsize=(9, 5.4))
    # a new family is appended, so that the committed figures keep their colours
    colors = dict(zip(["heuristic", "solver", "rollout", "mpc", "network", "oracle", "random", "other", "search"],
                      plt.get_cmap("tab10").colors, strict=False))
    x = "cpu_ms_per_step"
    for budget in BUDGETS_MS:
        ax.axvline(budget, color="0.6", linestyle=":", linewidth=1)
    for fam, g in result.groupby("family", sort=False):
        g = g.reset_index(drop=True)
        front = pareto(g[x].tolist(), g["iqm"].tolist())
        color = colors.get(fam)
        yerr = np.vstack([g["iqm"] - g["iqm_low"], g["iqm_high"] - g["iqm"]])
        ax.errorbar(g[x], g["iqm"], yerr=yerr, fmt="none", ecolor=color, capsize=2, alpha=0.6)
        on = g.index.isin(front)
        ax.scatter(g.loc[on, x], g.loc[on, "iqm"], color=color, s=18, zorder=3)
        ax.scatter(g.loc[~on, x], g.loc[~on, "iqm"], facecolors="none", edgecolors=color, s=18, zorder=3)
        ax.plot(g.loc[front, x], g.loc[front, "iqm"], color=color, linestyle="--" if fam == "oracle" else "-",
                label=fam)
        for _, r in g.iterrows():
            ax.annotate(r["policy"], (r[x], r["iqm"]), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("CPU ms per env-step (log; observe, decide and simulate; dotted: the budgets)")
    ax.set_ylabel(f"IQM of the normalized score, {split} (95% CI)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right", title="family: its Pareto front (hollow: dominated)", title_fontsize=7)
    ax.set_title(f"Score against compute: {split} split, {n} scenarios, seeds {seeds_text}")
    fig.tight_layout()
    files = [save_figure(fig, path_stem.with_suffix(".png")), save_figure(fig, path_stem.with_suffix(".svg"))]
    plt.close(fig)
    return files


__all__ = ["BUDGETS_MS", "committed_settings", "default_policies", "default_reuse", "family", "frontier", "pareto",
           "size", "stem", "verdicts"]
