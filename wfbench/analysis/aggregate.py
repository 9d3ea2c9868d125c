"""The aggregate over a suite's scenarios, computed by rliable (Agarwal et al., 2021).

IQM, mean and optimality gap with stratified bootstrap intervals, the probability of improvement
over a baseline, and performance profiles, on scores normalized per scenario
(:func:`wfbench.scenarios.normalize`) in a ``(runs, scenarios)`` matrix per policy; a run is a
seed, or a (training seed, evaluation seed) pair (:func:`pool_seeds`). Determinism: rliable's
bootstrap draws from NumPy's global generator, not the ``random_state`` it accepts, so each call
seeds that generator per policy and restores it after: identical inputs give identical bits, a
policy's interval does not depend on the others, and nobody else's ``np.random`` is disturbed
(``docs/suite.md``, "The aggregate").
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["AGGREGATE_NOTE", "STATISTICS", "Aggregate", "aggregate", "aggregate_cells", "aggregate_suite",
           "median_seed", "over_seeds", "pool_seeds", "score_matrix", "seed_scores"]

STATISTICS = ("iqm", "mean", "optimality_gap")
"""The aggregate statistics, in the order of the columns: IQM and mean higher is better, optimality gap lower.

(The per-step metric columns of the simulator are :data:`wfbench.core.kpis.METRICS`.)
"""

RUN_KEYS = ("train_seed", "seed")  # the columns that name a run, where present
# the suites' splits (wfbench.scenarios.SPLITS), reported in this order
SPLIT_ORDER = ("train", "heldout")


@contextlib.contextmanager
def _seeded(seed: int) -> Iterator[None]:
    """NumPy's global generator seeded for one rliable call, and the root logger left as the caller set it.

    rliable logs through absl, whose log call runs ``logging.basicConfig()`` when the root logger has no
    handler: that handler would hold whatever ``sys.stderr`` was then (a test's capture, a server's) for
    good. A ``NullHandler`` on the root for the call's length keeps the root as it was.
    """
    state = np.random.get_state()
    root = logging.getLogger()
    guard = logging.NullHandler() if not root.handlers else None
    if guard is not None:
        root.addHandler(guard)
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)
        if guard is not None:
            root.removeHandler(guard)


@dataclass(frozen=True)
class Aggregate:
    """The aggregate of several policies over the same scenarios.

    Attributes:
        table: one row per policy: ``policy``, ``runs``, ``scenarios``, and for each of
            :data:`STATISTICS` the point estimate with ``_low`` and ``_high`` (95% interval);
            with a baseline also ``p_improve`` (probability that the policy beats the
            baseline on a random scenario and pair of runs) with its interval.
        profiles: the performance profiles, long form: ``policy``, ``tau``, ``fraction``
            (of runs x scenarios scoring above tau), ``low``, ``high``.
        baseline: the policy the probability of improvement is taken over, or ``None``.
        scenarios: the scenario ids, in the matrices' column order.
    """

    table: pd.DataFrame
    profiles: pd.DataFrame
    baseline: str | None
    scenarios: tuple[str, ...]


def score_matrix(df: pd.DataFrame, value: str = "normalized",
                 scenarios: Sequence[str] | None = None) -> tuple[np.ndarray, list[str]]:
    """A per-(scenario, seed) frame as rliable's ``(runs, scenarios)`` matrix.

    A run is a ``seed`` (and a ``train_seed`` where the frame has one); every scenario must
    have the same runs.

    Args:
        df: rows with ``scenario``, ``seed`` and ``value`` (:func:`wfbench.evaluate_suite`'s frame).
        value: the score column.
        scenarios: the columns' order (default: as they first appear).

    Returns:
        The matrix and the scenario ids of its columns.

    Raises:
        ValueError: a scenario misses a run another one has.
    """
    keys = [k for k in RUN_KEYS if k in df.columns]
    ids = list(scenarios) if scenarios is not None else list(dict.fromkeys(df["scenario"]))
    wide = df.pivot_table(index=keys, columns="scenario", values=value, aggfunc="first").reindex(columns=ids)
    if wide.isna().to_numpy().any():
        missing = [c for c in ids if wide[c].isna().any()]
        raise ValueError(f"the scenarios {', '.join(map(str, missing))} lack runs that others have; every scenario "
                         "needs the same seeds")
    return wide.to_numpy(dtype=float), ids


def _iqm() -> Callable[[np.ndarray], float]:
    """The IQM of rliable (``rliable.metrics.aggregate_iqm``) without scipy's axis and NaN wrapper around it.

    rliable's IQM is ``scipy.stats.trim_mean(x, 0.25, axis=None)``, and scipy's decorator that handles
    ``axis`` and ``nan_policy`` costs about nine tenths of each call (0.37 of 0.40 ms on a 50 x 1
    matrix); the bootstrap calls it once per replication and entry, which made most of a board's
    ranking time. The function the decorator wraps gives the same bits for a finite matrix
    (``tests/analysis/test_aggregate.py`` compares the two, and the intervals, with rliable's own);
    a matrix with a NaN or infinity, or a scipy that exposes no wrapped function, gets rliable's.
    """
    import scipy.stats
    from rliable import metrics

    inner = getattr(scipy.stats.trim_mean, "__wrapped__", None)
    if inner is None:
        return metrics.aggregate_iqm
    def iqm(x: np.ndarray) -> float:
        return inner(x, 0.25, axis=None) if np.isfinite(x).all() else metrics.aggregate_iqm(x)

    return iqm


def aggregate(scores: Mapping[str, np.ndarray], baseline: str | None = None, seed: int = 0, reps: int = 5000,
              poi_reps: int = 1000, profile_reps: int = 1000, taus: np.ndarray | None = None,
              scenarios: Sequence[str] | None = None) -> Aggregate:
    """IQM, mean and optimality gap with 95% stratified bootstrap intervals, improvement and profiles.

    Args:
        scores: policy -> normalized scores ``(runs, scenarios)``; every matrix has the same scenarios
            (columns), the number of runs may differ.
        baseline: a policy of ``scores``: adds the probability of improvement of every other policy over
            it (:func:`rliable.metrics.probability_of_improvement`, intervals by rliable's stratified
            independent bootstrap).
        seed: the bootstrap's seed; the same inputs and seed give bit-identical results.
        reps: bootstrap replications of the metrics' intervals.
        poi_reps: bootstrap replications of the improvement's interval (fewer: rliable computes it with a
            Mann-Whitney U test per scenario and replication, about 10 ms each on 50 x 8 scores).
        profile_reps: bootstrap replications of the profiles' bands.
        taus: the thresholds of the performance profiles (default 101 points from ``min(0, lowest score)``
            to ``max(1, highest score)``).
        scenarios: the scenario ids of the columns, for the record.

    Returns:
        The :class:`Aggregate`.

    Raises:
        ValueError: no policies, matrices of different scenario counts, or a baseline not in ``scores``.
    """
    from rliable import library as rly
    from rliable import metrics

    if not scores:
        raise ValueError("no policies to aggregate")
    mats = {k: np.asarray(v, dtype=float) for k, v in scores.items()}
    widths = {m.shape[1] if m.ndim == 2 else -1 for m in mats.values()}
    if len(widths) != 1 or -1 in widths:
        raise ValueError("every policy's scores must be a (runs, scenarios) matrix over the same scenarios; got "
                         + ", ".join(f"{k}: {m.shape}" for k, m in mats.items()))
    if baseline is not None and baseline not in mats:
        raise ValueError(f"baseline {baseline!r} is not among the policies; allowed: {', '.join(mats)}")

    iqm = _iqm()

    def metric_values(x: np.ndarray) -> np.ndarray:
        return np.array([iqm(x), metrics.aggregate_mean(x), metrics.aggregate_optimality_gap(x)])

    rows = []
    for name, m in mats.items():
        with _seeded(seed):
            point, ci = rly.get_interval_estimates({name: m}, metric_values, reps=reps)
        row = {"policy": name, "runs": m.shape[0], "scenarios": m.shape[1]}
        for i, k in enumerate(STATISTICS):
            row[k], row[f"{k}_low"], row[f"{k}_high"] = float(point[name][i]), float(ci[name][0, i]), \
                float(ci[name][1, i])
        if baseline is not None:
            if name == baseline:
                row["p_improve"] = row["p_improve_low"] = row["p_improve_high"] = np.nan
            else:
                with _seeded(seed):
                    p, pci = rly.get_interval_estimates({name: [m, mats[baseline]]},
                                                        metrics.probability_of_improvement, reps=poi_reps)
                row["p_improve"], row["p_improve_low"], row["p_improve_high"] = float(p[name]), \
                    float(np.ravel(pci[name])[0]), float(np.ravel(pci[name])[1])
        rows.append(row)
    if taus is None:
        lo = min(0.0, min(float(m.min()) for m in mats.values()))
        hi = max(1.0, max(float(m.max()) for m in mats.values()))
        taus = np.linspace(lo, hi, 101)
    taus = np.asarray(taus, dtype=float)
    profiles = []
    for name, m in mats.items():
        with _seeded(seed):  # create_performance_profile takes no random state: the global one is seeded
            prof, band = rly.create_performance_profile({name: m}, taus, reps=profile_reps)
        profiles.append(pd.DataFrame({"policy": name, "tau": taus, "fraction": prof[name],
                                      "low": band[name][0], "high": band[name][1]}))
    n_cols = next(iter(widths))
    ids = tuple(scenarios) if scenarios is not None else tuple(str(i) for i in range(n_cols))
    return Aggregate(table=pd.DataFrame(rows), profiles=pd.concat(profiles, ignore_index=True), baseline=baseline,
                     scenarios=ids)


def aggregate_suite(frames: Mapping[str, pd.DataFrame], baseline: str | None = None, seed: int = 0,
                    reps: int = 5000, poi_reps: int = 1000, profile_reps: int = 1000,
                    value: str = "normalized") -> dict[str, Aggregate]:
    """The aggregate of per-(scenario, seed) frames, reported separately for each split present.

    Args:
        frames: policy -> a frame with ``scenario``, ``split``, ``seed`` and ``value`` columns
            (:func:`wfbench.evaluate_suite`'s).
        baseline: the policy the probability of improvement is taken over (or ``None``).
        seed: the bootstrap's seed.
        reps: bootstrap replications of the metrics' intervals.
        poi_reps: bootstrap replications of the improvement's interval.
        profile_reps: bootstrap replications of the profiles' bands.
        value: the score column.

    Returns:
        split -> :class:`Aggregate`, for the splits present (``"train"`` before ``"heldout"``).
    """
    out = {}
    first = next(iter(frames.values()))
    present = list(dict.fromkeys(first["split"]))
    for split in sorted(present, key=lambda s: (SPLIT_ORDER.index(s) if s in SPLIT_ORDER else len(SPLIT_ORDER), s)):
        ids = list(dict.fromkeys(first.loc[first["split"] == split, "scenario"]))
        if not ids:
            continue
        mats = {name: score_matrix(df[df["split"] == split], value, ids)[0] for name, df in frames.items()}
        out[split] = aggregate(mats, baseline=baseline, seed=seed, reps=reps, poi_reps=poi_reps,
                               profile_reps=profile_reps, scenarios=ids)
    return out


AGGREGATE_NOTE = ("Aggregate over the split's scenarios and runs (rliable): IQM and mean of the normalized score, "
                  "higher is better; optimality gap = mean shortfall below 1 (the bound), lower is better; 95% "
                  "stratified bootstrap intervals over runs within each scenario.")


def aggregate_cells(aggs: Mapping[str, Aggregate]) -> tuple[list[str], list[list[str]]]:
    """Header and text cells of aggregates per split: IQM, mean and optimality gap with their 95% intervals.

    A column of the probability of improvement over the baseline is added when the aggregates have one.
    """
    improvement = any(a.baseline is not None for a in aggs.values())
    header = ["Split", "Policy", "Scenarios x runs", "IQM [95% CI]", "Mean [95% CI]", "Optimality gap [95% CI]"]
    if improvement:
        header.append("P(improvement over baseline) [95% CI]")
    rows = []
    for split, agg in aggs.items():
        for _, r in agg.table.iterrows():
            cells = [split, str(r["policy"]), f"{r['scenarios']} x {r['runs']}",
                     *[f"{r[k]:.3f} [{r[k + '_low']:.3f}, {r[k + '_high']:.3f}]" for k in STATISTICS]]
            if improvement:
                cells.append("(baseline)" if r["policy"] == agg.baseline else
                             f"{r['p_improve']:.2f} [{r['p_improve_low']:.2f}, {r['p_improve_high']:.2f}]")
            rows.append(cells)
    return header, rows


def over_seeds(method: str, n: int) -> str:
    """The name of a learned method's aggregate over its ``n`` training seeds, e.g. ``ppo-general (5 seeds)``."""
    return f"{method} ({n} seeds)"


def pool_seeds(members: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """The runs of a learned method's training seeds as one frame: a run is a (training seed, evaluation seed) pair.

    Args:
        members: member (a training seed's name, e.g. ``ppo-general#seed0``) -> its per-(scenario, seed)
            frame (:func:`wfbench.evaluate_suite`'s, or a suite result's rows), all on the same scenarios and seeds.

    Returns:
        The frames stacked with a ``train_seed`` column holding the member's name, so that
        :func:`score_matrix` (and :func:`aggregate_suite`) make the ``(members x seeds, scenarios)`` matrix.

    Raises:
        ValueError: no members.
    """
    if not members:
        raise ValueError("no training seeds to pool")
    return pd.concat([df.assign(train_seed=name) for name, df in members.items()], ignore_index=True)


def seed_scores(members: Mapping[str, pd.DataFrame], value: str = "normalized") -> pd.DataFrame:
    """Each training seed's own scores: its IQM and mean per split, and its mean score per scenario.

    Args:
        members: member name -> its per-(scenario, seed) frame with ``scenario``, ``split``, ``seed`` and ``value``.
        value: the score column.

    Returns:
        One row per member, in the mapping's order: ``member``, ``iqm_<split>`` and ``mean_<split>`` for each
        split present (rliable's IQM and mean over that member's seeds x the split's scenarios, no interval:
        the interval is the pooled one's), and one column per scenario (its mean ``value``).
    """
    from rliable import metrics

    rows = []
    for name, df in members.items():
        row: dict = {"member": name}
        present = list(dict.fromkeys(df["split"]))
        for split in sorted(present, key=lambda s: (SPLIT_ORDER.index(s) if s in SPLIT_ORDER else len(SPLIT_ORDER),
                                                    s)):
            m, _ = score_matrix(df[df["split"] == split], value)
            row[f"iqm_{split}"] = float(metrics.aggregate_iqm(m))
            row[f"mean_{split}"] = float(metrics.aggregate_mean(m))
        for sc, g in df.groupby("scenario", sort=False):
            row[str(sc)] = float(g[value].mean())
        rows.append(row)
    return pd.DataFrame(rows)


def median_seed(scores: Mapping[str, float]) -> str:
    """The training seed to ship: the one whose score is the median of the seeds' scores, stated before any test.

    The rule of issue #28 (docs/suite.md, "Learned methods over training seeds"): ``scores`` are the
    members' mean scores on the public seeds of the training scenarios (never the test seeds); the
    pick is the middle one once sorted, the 3rd of 5 (for an even count the lower of the two middle
    ones). Equal scores keep the mapping's order (seed order), so ties go to the lower seed.

    Raises:
        ValueError: no scores, or a score that is not a finite number.
    """
    if not scores:
        raise ValueError("no training seeds to choose from")
    bad = [k for k, v in scores.items() if not np.isfinite(float(v))]
    if bad:
        raise ValueError(f"the scores of {', '.join(map(str, bad))} are not finite numbers")
    order = sorted(scores, key=lambda k: float(scores[k]))  # stable: ties stay in seed order
    return order[(len(order) - 1) // 2]
