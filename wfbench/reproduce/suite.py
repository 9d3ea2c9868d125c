"""The suite: every built-in policy on every scenario of suite-v1, normalized, aggregated per split, with checks.

wfbench's own verdict across many worlds (issue #27): every policy (the built-ins, the tuned
files, every shipped network zero-shot, a learned method's training seeds, the oracle) runs on
every scenario through :func:`wfbench.evaluate`, beside the proven bound. :func:`suite` writes
``suite-scores``, ``suite-aggregate`` (:mod:`wfbench.analysis.aggregate`), ``suite-profile-<split>``,
``suite-scaling``, ``suite-checks`` and ``suite-per-seed``. Each (policy, scenario) piece is cached
under ``cache/`` with the scenario's hash and the seeds, so a stopped run resumes and a changed
scenario is run again. What each file holds: ``docs/suite.md``, "How to run" and "Learned methods
over training seeds".
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.analysis.aggregate import (
    AGGREGATE_NOTE,
    aggregate_cells,
    aggregate_suite,
    over_seeds,
    pool_seeds,
    seed_scores,
)
from wfbench.analysis.tables import markdown_table
from wfbench.core.kpis import SCORE
from wfbench.core.seeds import describe, resolve_seeds
from wfbench.harness.backends import Execution
from wfbench.policies.registry import LINEUPS
from wfbench.reproduce import pieces, provenance
from wfbench.reproduce.common import PROCESS, Output, Progress, checkout_root, write
from wfbench.scenarios import Suite, SuiteScenario, get_suite, normalize

BUILTIN = LINEUPS["suite"]  # the built-ins every suite run plays (the registry's lineups say why these)
ORACLE = "oracle"
BASELINE = "heuristic"  # the probability of improvement is taken over it
BUDGET = ("decision_ms_p50", "decision_ms_p99", "cpu_s")  # the evaluator's cost columns, used where present
BOUND_SLACK = 1e-9  # a policy's NSW may exceed the bound by floating-point rounding only


# the lookaheads every suite run plays (issue #53, item 4): both presets of the tuned solver's rollout, the MPC the
# frontier carries and the learned side's search at its 1 ms and 10 ms presets; the other presets are the frontier's, or
# asked for by name
LOOKAHEADS = ("rollout-solver-tuned-1ms", "rollout-solver-tuned", "mpc-ma-calibrated", "search-scalefree-general-1ms",
              "search-scalefree-general")


def default_policies(networks: bool = True) -> list[str]:
    """The built-ins, the shipped networks (zero-shot), the lookaheads (:data:`LOOKAHEADS`) and the oracle.

    Without ``networks`` the shipped networks and the lookaheads that search with one are left out.
    """
    from wfbench.policies.registry import entry, learned_names

    lookaheads = [n for n in LOOKAHEADS if networks or entry(n).family != "search"]
    return [*BUILTIN, *(learned_names() if networks else []), *lookaheads, ORACLE]


def with_members(names: Sequence[str], members: bool = True) -> tuple[list[str], dict[str, list[str]]]:
    """``names`` with each learned method's training seeds (present ones) after it, and method -> its members.

    Without ``members`` the names are kept as given and no method has members (only the shipped picks play).
    """
    from wfbench.policies.registry import seed_members

    methods = {n: seed_members(n) if members else [] for n in names}
    methods = {n: m for n, m in methods.items() if m}
    out = []
    for n in names:
        out += [n, *methods.get(n, [])]
    return list(dict.fromkeys(out)), methods


def family(policy: str) -> str:
    """A policy's family in the scaling figure: random, heuristic, solver, network, lookahead or oracle.

    The scaling figure draws one line a family, the median of its policies' costs.
    """
    from wfbench.policies.registry import parse_spec

    kind = parse_spec(policy).kind
    if kind in ("learned", "member", "checkpoint"):
        return "network"
    if kind == "lookahead":
        return "lookahead"
    for name in ("oracle", "solver", "heuristic", "random"):
        if policy.startswith(name):
            return name
    return "other"


def _chosen(suite: Suite, scenarios: Sequence[str] | None) -> list[SuiteScenario]:
    return [suite.scenario(x) for x in scenarios] if scenarios else list(suite.scenarios)


def size(policies: Sequence[str] | None = None, scenarios: Sequence[str] | None = None, networks: bool = True,
         suite_name: str = "suite-v1", members: bool = True, **_: object) -> int:
    """The evaluations :func:`suite` runs (for a progress bar): each policy, training seed and bound per scenario."""
    n_policies = len(with_members(list(policies) if policies else default_policies(networks), members)[0])
    return (n_policies + 1) * len(_chosen(get_suite(suite_name), scenarios))


def committed_runs() -> tuple[Path, ...]:
    """The checkout's committed suite runs (``docs/results/*`` with a ``cache/``); none in an installed copy.

    Where a plan's estimates read what a policy costs: their pieces are read for costs only, never reused.
    """
    root = checkout_root()
    results = None if root is None else root / "docs" / "results"
    return () if results is None else tuple(sorted(p for p in results.iterdir() if (p / "cache").is_dir()))


def _cache_path(out: Path, policy: str, scenario: SuiteScenario) -> Path:
    return pieces.piece_path(out, policy, scenario)


_run = pieces.play  # what plays a missing piece (module-level: the tests replace it)


def _figure_profiles(agg, split: str, path_stem: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.analysis.plots import save_figure

    fig, ax = plt.subplots(figsize=(6.5, 4))
    colors = plt.get_cmap("tab20").colors  # more policies than tab10 has colours: no two lines share one
    for i, (name, g) in enumerate(agg.profiles.groupby("policy", sort=False)):
        line, = ax.plot(g["tau"], g["fraction"], label=name, color=colors[(2 * i) % 20 + (2 * i) // 20 % 2],
                        linestyle="--" if family(str(name)) == "oracle" else "-")
        ax.fill_between(g["tau"], g["low"], g["high"], alpha=0.15, color=line.get_color(), linewidth=0)
    ax.set_xlabel("normalized score tau (0 random, 1 the proven bound)")
    ax.set_ylabel("fraction of runs x scenarios above tau")
    ax.set_title(f"Performance profiles, {split} split ({len(agg.scenarios)} scenarios), 95% bands")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    files = [save_figure(fig, path_stem.with_suffix(".png")), save_figure(fig, path_stem.with_suffix(".svg"))]
    plt.close(fig)
    return files


def _figure_scaling(scaling: pd.DataFrame, path_stem: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wfbench.analysis.plots import save_figure

    by = scaling.groupby(["family", "entities"], sort=True)[["env_steps_per_s", "decision_ms"]].median().reset_index()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for fam, g in by.groupby("family", sort=True):
        axes[0].plot(g["entities"], g["env_steps_per_s"], marker="o", label=fam)
        axes[1].plot(g["entities"], g["decision_ms"], marker="o", label=fam)
    for ax, label in zip(axes, ("env-steps per second (one core's worth)", "decision latency, ms per environment"),
                         strict=True):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("facilities + people at start")
        ax.set_ylabel(label)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Scaling per policy family: median over the family's policies at each scenario size")
    fig.tight_layout()
    files = [save_figure(fig, path_stem.with_suffix(".png")), save_figure(fig, path_stem.with_suffix(".svg"))]
    plt.close(fig)
    return files


def suite(out: Path, runs: int = 50, execution: Execution = PROCESS, progress: Progress = None,
          seeds: str | Sequence[int] | None = None, policies: Sequence[str] | None = None,
          scenarios: Sequence[str] | None = None, networks: bool = True, members: bool = True,
          suite_name: str = "suite-v1", reps: int = 5000, poi_reps: int = 1000,
          announce: Callable[[str], None] | None = None, plan_only: bool = False,
          reuse: Sequence[str | Path] = ()) -> Output:
    """Every policy on every scenario of the suite, normalized and aggregated, with the bound and oracle checks.

    Args:
        out: the output folder (its ``cache/`` keeps each finished (policy, scenario) result).
        runs: seeds 0..runs-1 when ``seeds`` is not given.
        execution: where the evaluations run (:class:`~wfbench.harness.backends.Execution`;
            numbers do not depend on it).
        progress: called with the name of each evaluation as it starts.
        seeds: the seeds (a set name such as ``"test"`` or a list); default ``range(runs)``.
        policies: the policies (default :func:`default_policies`); the bound is always added, and so are
            the training seeds of a learned method (:func:`wfbench.policies.registry.seed_members`).
        scenarios: a subset of the suite's ids or presets (default all).
        networks: include the shipped networks in the default policies.
        members: also play each learned method's training seeds (without it, only the shipped picks: a
            reference's candidates are the picks, and on ``city-v1`` the five seeds of a network cost hours).
        suite_name: the suite.
        reps: bootstrap replications of the aggregate's intervals.
        poi_reps: bootstrap replications of the probability of improvement's interval.
        announce: called once with what will be played and its estimated CPU time
            (:func:`wfbench.reproduce.pieces.describe_plan`) before anything is played.
        plan_only: stop after announcing the plan (``files`` empty; the text is the plan).
        reuse: more suite run folders whose ``cache/`` pieces are read, in order, after ``out``'s;
            what is played is written to ``out`` only (e.g. the committed runs, to check a new
            reference against every piece they hold).

    Returns:
        The text (scores, aggregate, checks) and the files written.
    """
    s = get_suite(suite_name)
    chosen = _chosen(s, scenarios)
    seed_list = resolve_seeds(seeds) if seeds is not None else list(range(runs))
    names, methods = with_members(list(dict.fromkeys(policies)) if policies else default_policies(networks), members)
    members = {m for ms in methods.values() for m in ms}
    provenance.start()  # the code this run starts with is the code its pieces record
    folders = [out, *(Path(r) for r in reuse)]
    todo = pieces.plan(folders, [*names, "bound"], chosen, seed_list, others=s.scenarios, costs=committed_runs())
    text = pieces.describe_plan(todo, execution.workers or os.cpu_count() or 1)
    if announce:
        announce(text)
    if plan_only:
        return Output(text, [])
    frames: dict[str, list[pd.DataFrame]] = {n: [] for n in names}
    bound: dict[str, np.ndarray] = {}
    failures: list[tuple[str, str, str]] = []
    scaling = []
    for sc in chosen:
        for name in [*names, "bound"]:
            if progress:
                progress(f"{sc.id}: {name}")
            try:  # a stored piece, cut to the seeds, or only its missing seeds played (wfbench.reproduce.pieces)
                df = pieces.obtain(folders, out, name, sc, seed_list, execution, play_fn=_run)
            except Exception as exc:  # noqa: BLE001 - a long run reports a failing pair and goes on
                failures.append((sc.id, name, f"{type(exc).__name__}: {exc}".splitlines()[0]))
                continue
            if name == "bound":
                bound[sc.id] = df[SCORE].to_numpy()
                continue
            df = df.copy()
            df.insert(0, "normalized", normalize(df[SCORE].to_numpy(), sc.id, s))
            df.insert(0, "split", sc.split)
            df.insert(0, "scenario", sc.id)
            frames[name].append(df)
            if name not in members:  # a training seed costs what its shipped pick costs
                scaling.append(_scaling_row(name, sc, df))
    runs_by = {n: pd.concat(f, ignore_index=True) for n, f in frames.items() if len(f) == len(chosen)}
    files: list[Path] = []
    out.mkdir(parents=True, exist_ok=True)

    # the scores per scenario and policy
    records = []
    for name, df in runs_by.items():
        for sc_id, g in df.groupby("scenario", sort=False):
            records.append({"scenario": sc_id, "split": g["split"].iloc[0], "policy": name,
                            "nsw": float(g[SCORE].mean()), "normalized": float(g["normalized"].mean()),
                            "seeds": len(g)})
    for sc in chosen:
        if sc.id in bound:
            records.append({"scenario": sc.id, "split": sc.split, "policy": "bound", "nsw": float(bound[sc.id].mean()),
                            "normalized": float(np.mean(normalize(bound[sc.id], sc.id, s))),
                            "seeds": len(bound[sc.id])})
    scores = pd.DataFrame(records)
    columns = [*(n for n in runs_by if n not in members), "bound"]
    picks = _picks(methods)
    header = ["Scenario", "Split", *(picks.get(c, c) for c in columns)]
    rows = []
    for sc in chosen:
        cells = [sc.id, sc.split]
        for name in columns:
            r = scores[(scores["scenario"] == sc.id) & (scores["policy"] == name)] if len(scores) else scores
            cells.append(f"{r['normalized'].iloc[0]:.3f} ({r['nsw'].iloc[0]:.3f})" if len(r) else "-")
        rows.append(cells)
    seeds_text = describe(seed_list)
    scores_md = "\n".join([
        f"{s.name} (hash {s.hash}), seeds {seeds_text}: mean normalized score (raw mean NSW) per scenario and "
        "policy; normalized = (NSW - random_ref) / (bound_ref - random_ref), 0 the random policy and 1 the mean "
        "proven bound (docs/suite.md). The networks run zero-shot (trained on paper-64); the oracle reads the "
        "future (not deployable); 'bound' is the proven upper bound, not a policy."
        + (" The training seeds of a learned method are in suite-per-seed (and in the CSV here)." if methods else ""),
        "", markdown_table(header, rows)])
    files += write(out, "suite-scores", scores_md, scores)

    # the aggregate per split
    baseline = BASELINE if BASELINE in runs_by else None
    pooled: dict[str, tuple[str, list[str]]] = {}  # the aggregate row's name -> (method, the members it pools)
    agg_frames: dict[str, pd.DataFrame] = {}

    def add_pooled(method: str) -> None:  # the row over a method's seeds that ran on every scenario
        done = [m for m in methods.get(method, []) if m in runs_by]
        if done:
            pooled[over_seeds(method, len(done))] = (method, done)
            agg_frames[over_seeds(method, len(done))] = pool_seeds({m: runs_by[m] for m in done})

    for name, df in runs_by.items():
        if name not in members:
            agg_frames[name] = df
            add_pooled(name)  # right after its shipped pick
    for method in methods:  # a method whose shipped pick failed: its seeds are still pooled
        if method not in runs_by:
            add_pooled(method)
    aggs = aggregate_suite(agg_frames, baseline=baseline, reps=reps, poi_reps=poi_reps) if agg_frames else {}
    agg_table = pd.concat([a.table.assign(split=split) for split, a in aggs.items()], ignore_index=True) \
        if aggs else pd.DataFrame()
    agg_header, agg_rows = aggregate_cells(aggs)
    for row in agg_rows:  # the shipped pick's row says so (the CSV keeps the policy's name)
        if row[1] in picks:
            row[1] = picks[row[1]]
    agg_md = "\n".join([f"Aggregate of {s.name} per split, seeds {seeds_text}"
                        + (f"; probability of improvement over {baseline}" if baseline else "") + ".", "",
                        markdown_table(agg_header, agg_rows) if aggs else "(no policy ran on every scenario)",
                        "", AGGREGATE_NOTE + (SEEDS_NOTE if pooled else "")])
    files += write(out, "suite-aggregate", agg_md, agg_table)
    for split, agg in aggs.items():
        agg.profiles.to_csv(out / f"suite-profile-{split}.csv", index=False)
        files += [out / f"suite-profile-{split}.csv", *_figure_profiles(agg, split, out / f"suite-profile-{split}")]

    # the training seeds
    per_seed_md = ""
    if methods:
        per_seed, per_seed_md = _per_seed(methods, runs_by, aggs, pooled, chosen, seeds_text)
        files += write(out, "suite-per-seed", per_seed_md, per_seed)

    # the scaling
    scale = pd.DataFrame(scaling)
    if len(scale):
        scale.to_csv(out / "suite-scaling.csv", index=False)
        files += [out / "suite-scaling.csv", *_figure_scaling(scale, out / "suite-scaling")]

    # the checks
    checks, check_rows = _checks(chosen, runs_by, bound)
    holds = all(c["bound_holds"] for c in checks)
    oracle_ok = [c["oracle_at_least_deployable"] for c in checks if c["oracle_at_least_deployable"] is not None]
    oracle_ran = any(c["oracle_nsw"] is not None for c in checks)
    summary = (f"The bound holds: {'yes' if holds else 'NO'} (no policy above it on any seed"
               f"{'' if holds else ': see the rows marked NO'}). "
               + (f"The {checks[0]['oracle']} is at least every deployable policy on {sum(oracle_ok)} of "
                  f"{len(oracle_ok)} scenarios." if oracle_ok else
                  f"The {checks[0]['oracle']} ran with no deployable candidate of it beside: nothing to compare."
                  if oracle_ran else "The oracle was not run."))
    beyond = [c["scenario"] for c in checks if json.loads(c["above_oracle_outside"])]
    if beyond:  # its candidates were fixed before these policies: a newer reference plays them
        summary += (f" Deployable policies it does not play are above it on {len(beyond)} scenario(s): "
                    f"{', '.join(beyond)} (a newer reference plays them: docs/hindsight.md, \"Versioned references\").")
    checks_md = "\n".join([summary, "", markdown_table(["Scenario", "Seeds above the bound (policy: count)",
                                                        "Oracle mean NSW", "Best deployable (mean NSW)",
                                                        "Oracle >= every deployable",
                                                        "Deployable it does not play, above it (mean NSW)"],
                                                       check_rows)])
    if failures:
        checks_md += "\n\nFailed (not cached; a rerun tries them again):\n\n" + markdown_table(
            ["Scenario", "Policy", "Error"], [list(f) for f in failures])
    files += write(out, "suite-checks", checks_md, pd.DataFrame(checks))
    text = "\n\n".join([x for x in (scores_md, agg_md, per_seed_md, checks_md) if x])
    return Output(text, files)


SEEDS_NOTE = (" 'METHOD (N seeds)' pools the runs of a learned method's N training seeds (a run is a (training seed, "
              "evaluation seed) pair); the method's own row is its shipped pick, one of those seeds chosen before "
              "any test (the median on the public seeds of the training scenarios; docs/suite.md).")


def _picks(methods: dict[str, list[str]]) -> dict[str, str]:
    """How the markdown names each method's shipped pick: ``ppo-general (shipped pick: seed2)``."""
    from wfbench.policies.registry import parse_member, shipped_member

    out = {}
    for method in methods:
        pick = shipped_member(method)
        out[method] = f"{method} (shipped pick: " + (f"seed{parse_member(pick)[1]})" if pick else "no seed's copy)")
    return out


def _per_seed(methods: dict[str, list[str]], runs_by: dict[str, pd.DataFrame], aggs: dict,
              pooled: dict[str, tuple[str, list[str]]], chosen: list[SuiteScenario],
              seeds_text: str) -> tuple[pd.DataFrame, str]:
    """Each training seed's scores (:func:`wfbench.analysis.aggregate.seed_scores`) per method, and its markdown."""
    from wfbench.policies.registry import shipped_member

    frames, parts = [], []
    splits = [sp for sp in ("train", "heldout") if any(sc.split == sp for sc in chosen)]
    for method, ms in methods.items():
        done = [m for m in ms if m in runs_by]
        pick = shipped_member(method)
        if not done:
            parts.append(f"{method}: no training seed ran on every scenario.")
            continue
        t = seed_scores({m: runs_by[m] for m in done})
        t.insert(0, "shipped", t["member"] == pick)
        t.insert(0, "method", method)
        frames.append(t)
        header = ["Training seed", *(f"{sp} IQM" for sp in splits), *(sc.id for sc in chosen)]
        rows = []
        for _, r in t.iterrows():
            rows.append([r["member"] + (" (shipped pick)" if r["shipped"] else ""),
                         *(f"{r[f'iqm_{sp}']:.3f}" for sp in splits), *(f"{r[sc.id]:.3f}" for sc in chosen)])
        name = over_seeds(method, len(done))
        if name in pooled:
            cells = []
            for sp in splits:
                a = aggs[sp].table.set_index("policy") if sp in aggs else None
                cells.append(f"{a.loc[name, 'iqm']:.3f} [{a.loc[name, 'iqm_low']:.3f}, {a.loc[name, 'iqm_high']:.3f}]"
                             if a is not None and name in a.index else "-")
            means = [float(np.mean([runs_by[m].loc[runs_by[m]["scenario"] == sc.id, "normalized"].mean()
                                    for m in done])) for sc in chosen]
            rows.append([f"**{name}**", *cells, *(f"{v:.3f}" for v in means)])
        parts.append(f"{method}, {len(done)} of {len(ms)} training seeds"
                     + (f", shipped pick {pick}" if pick else ", no seed is byte for byte the shipped file") + ":\n\n"
                     + markdown_table(header, rows))
    md = "\n\n".join([f"The training seeds of each learned method, seeds {seeds_text}: each seed's IQM of the "
                      "normalized score per split and its mean per scenario; the last row pools them (IQM with its 95% "
                      "stratified bootstrap interval over (training seed, evaluation seed) runs within each "
                      "scenario). The shipped pick is the seed with the median mean score on the public seeds of "
                      "the training scenarios, chosen before any test (docs/suite.md).", *parts])
    return (pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()), md


def _scaling_row(policy: str, scenario: SuiteScenario, df: pd.DataFrame) -> dict:
    c = scenario.config
    steps = float(df["episode_length"].mean()) if "episode_length" in df.columns else float(c.horizon)
    if all(k in df.columns for k in BUDGET):
        decision_ms = float(df["decision_ms_p50"].mean())
        env_steps_per_s = steps / float(df["cpu_s"].mean()) if float(df["cpu_s"].mean()) > 0 else np.nan
        source = "budget columns (cpu_s, decision_ms_p50)"
    else:
        wall = df.attrs.get("wall_s")
        per_step_s = wall / (len(df) * steps) if wall else np.nan
        decision_ms, env_steps_per_s = per_step_s * 1e3, 1.0 / per_step_s if per_step_s else np.nan
        source = "episode wall time / steps"
    return {"policy": policy, "family": family(policy), "scenario": scenario.id,
            "facilities": c.initial_facilities, "people": c.initial_personnel,
            "entities": c.initial_facilities + c.initial_personnel, "max_facilities": c.max_facilities,
            "max_personnel": c.max_personnel, "env_steps_per_s": env_steps_per_s, "decision_ms": decision_ms,
            "source": source}


def outside_oracle(name: str, oracle: str = ORACLE) -> bool:
    """Whether ``name`` is a policy ``oracle`` does not play.

    Each oracle plays the candidates of its reference (:mod:`wfbench.policies.oracle.references`).
    A training seed ``METHOD#seedK`` is played where its reference lists it (v3 on), or where it
    is its method's shipped pick (the same file) and the reference lists the method.
    """
    from wfbench.policies.oracle import references
    from wfbench.policies.registry import parse_member, shipped_member

    member = parse_member(name)
    if member is not None and not member[2] and references.outside(name, oracle) \
            and not references.outside(member[0], oracle):
        return shipped_member(member[0]) != name  # reads the checkpoints: asked only where it decides
    return references.outside(name, oracle)


def _checks(chosen: list[SuiteScenario], runs_by: dict[str, pd.DataFrame],
            bound: dict[str, np.ndarray]) -> tuple[list[dict], list[list[str]]]:
    """Per scenario: the seeds where a policy is above the bound, and whether the oracle beats every deployable.

    The oracle checked is, per scenario, the newest reference that ran there (``oracle-v3``, else
    ``oracle-v2``, else ``oracle``), against the deployable policies it plays; the deployable
    policies it does not play whose mean is above it are listed beside (``above_oracle_outside``:
    a reference made before them does not claim them).
    """
    from wfbench.policies.oracle import references

    checks, rows = [], []
    outside_of: dict[tuple[str, str], bool] = {}  # (policy, oracle) -> outside_oracle: the same on every scenario
    for sc in chosen:
        ran = [n for n in references.ORACLES if n in runs_by and (runs_by[n]["scenario"] == sc.id).any()]
        checked = ran[-1] if ran else ORACLE
        for name in runs_by:
            if (name, checked) not in outside_of:
                outside_of[name, checked] = outside_oracle(name, checked)
        above: dict[str, int] = {}
        means = {}
        for name, df in runs_by.items():
            g = df[df["scenario"] == sc.id]
            means[name] = float(g[SCORE].mean())
            if sc.id in bound:
                above[name] = int((g[SCORE].to_numpy() > bound[sc.id] + BOUND_SLACK).sum())
        # the policies the oracle is the best in hindsight of (its candidates, a shipped pick's training seed)
        deployable = {n: m for n, m in means.items() if family(n) != "oracle" and not outside_of[n, checked]}
        oracle = means.get(checked)
        best = max(deployable, key=deployable.get) if deployable else None
        ok = None if oracle is None or best is None else bool(oracle >= deployable[best])
        outside = {} if oracle is None else dict(sorted(
            ((n, round(m, 4)) for n, m in means.items()
             if family(n) != "oracle" and outside_of[n, checked] and m > oracle), key=lambda nm: -nm[1]))
        bad = {n: k for n, k in above.items() if k}
        checks.append({"scenario": sc.id, "split": sc.split, "oracle": checked, "bound_checked": sc.id in bound,
                       "bound_holds": not bad, "above_bound": json.dumps(bad), "oracle_nsw": oracle,
                       "best_deployable": best, "best_deployable_nsw": deployable.get(best) if best else None,
                       "oracle_at_least_deployable": ok, "above_oracle_outside": json.dumps(outside)})
        rows.append([sc.id, ("none" if sc.id in bound else "(bound not computed)") if not bad else
                     "NO: " + ", ".join(f"{n}: {k}" for n, k in bad.items()),
                     "-" if oracle is None else f"{oracle:.4f}",
                     "-" if best is None else f"{best} ({deployable[best]:.4f})",
                     "-" if ok is None else ("yes" if ok else "NO"),
                     "-" if oracle is None else ", ".join(f"{n} ({m:.4f})" for n, m in outside.items()) or "none"])
    return checks, rows
