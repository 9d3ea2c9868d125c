"""The aggregate over scenarios (rliable): bit-identical given a seed, per split, with the improvement."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.stats

from wfbench.analysis.aggregate import STATISTICS, aggregate, aggregate_suite, score_matrix

FAST = {"reps": 200, "poi_reps": 30, "profile_reps": 50}


def _scores():
    rng = np.random.default_rng(7)
    return {"good": rng.normal(0.7, 0.05, (20, 4)), "base": rng.normal(0.4, 0.05, (20, 4)),
            "few": rng.normal(0.4, 0.05, (6, 4))}


@pytest.mark.slow
def test_aggregate__identical_inputs_give_bit_identical_results_and_leave_numpy_state_alone():
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    a = aggregate(_scores(), baseline="base", seed=3, **FAST)
    assert np.array_equal(np.random.get_state()[1], before)
    b = aggregate(_scores(), baseline="base", seed=3, **FAST)
    pd.testing.assert_frame_equal(a.table, b.table, check_exact=True)
    pd.testing.assert_frame_equal(a.profiles, b.profiles, check_exact=True)
    c = aggregate(_scores(), baseline="base", seed=4, **FAST)
    assert not np.array_equal(a.table["iqm_low"], c.table["iqm_low"])


def test_aggregate__a_policy_s_interval_does_not_depend_on_the_others():
    s = _scores()
    alone = aggregate({"good": s["good"]}, seed=3, **FAST).table.iloc[0]
    together = aggregate(s, seed=3, **FAST).table.set_index("policy").loc["good"]
    for k in STATISTICS:
        assert alone[k] == together[k] and alone[f"{k}_low"] == together[f"{k}_low"]


def test_aggregate__points_are_rliable_s_metrics_inside_their_intervals():
    s = _scores()
    t = aggregate(s, baseline="base", **FAST).table.set_index("policy")
    assert t.loc["good", "iqm"] == pytest.approx(scipy.stats.trim_mean(s["good"], 0.25, axis=None))
    assert t.loc["good", "mean"] == pytest.approx(s["good"].mean())
    assert t.loc["good", "optimality_gap"] == pytest.approx(1 - np.minimum(s["good"], 1).mean())
    for k in STATISTICS:
        assert (t[f"{k}_low"] <= t[k]).all() and (t[k] <= t[f"{k}_high"]).all()
    assert t.loc["good", "p_improve"] == 1.0 and np.isnan(t.loc["base", "p_improve"])
    assert 0.2 < t.loc["few", "p_improve"] < 0.8
    assert list(t["runs"]) == [20, 20, 6]


def test_aggregate__profiles_fall_from_1_to_0_over_the_thresholds():
    p = aggregate({"good": _scores()["good"]}, **FAST).profiles
    assert p["tau"].iloc[0] == 0.0 and p["tau"].iloc[-1] == 1.0 and len(p) == 101
    assert p["fraction"].iloc[0] == 1.0 and p["fraction"].iloc[-1] == 0.0
    assert (np.diff(p["fraction"].to_numpy()) <= 0).all()


def test_aggregate__bad_input_says_what_is_allowed():
    with pytest.raises(ValueError, match="baseline 'x' is not among the policies; allowed: good, base, few"):
        aggregate(_scores(), baseline="x", **FAST)
    with pytest.raises(ValueError, match="same scenarios"):
        aggregate({"a": np.zeros((3, 4)), "b": np.zeros((3, 5))}, **FAST)


def _frame(shift: float) -> pd.DataFrame:
    rows = [{"scenario": sc, "split": split, "seed": seed, "normalized": shift + 0.01 * seed + 0.1 * k}
            for k, (sc, split) in enumerate([("a-v1", "train"), ("b-v1", "train"), ("c-v1", "heldout")])
            for seed in range(5)]
    return pd.DataFrame(rows)


def test_score_matrix__runs_by_scenarios_and_missing_runs_refused():
    m, ids = score_matrix(_frame(0.0))
    assert ids == ["a-v1", "b-v1", "c-v1"] and m.shape == (5, 3)
    assert m[2, 1] == pytest.approx(0.02 + 0.1)
    with pytest.raises(ValueError, match="the scenarios b-v1 lack runs that others have"):
        score_matrix(_frame(0.0).drop(index=7))


def test_aggregate_suite__reports_each_split_separately():
    out = aggregate_suite({"x": _frame(0.5), "y": _frame(0.0)}, baseline="y", **FAST)
    assert list(out) == ["train", "heldout"]
    assert out["train"].scenarios == ("a-v1", "b-v1") and out["heldout"].scenarios == ("c-v1",)
    t = out["heldout"].table.set_index("policy")
    assert t.loc["x", "mean"] == pytest.approx(0.5 + 0.2 + 0.02)
    assert t.loc["x", "p_improve"] == 1.0


def test_aggregate__leaves_the_root_logger_unconfigured(monkeypatch):
    import logging

    root = logging.getLogger()
    monkeypatch.setattr(root, "handlers", [])  # as in a process that configured no logging
    rng = np.random.default_rng(0)
    aggregate({"a": rng.random((5, 2)), "b": rng.random((5, 2))}, baseline="b", reps=20, poi_reps=10,
              profile_reps=5)
    assert root.handlers == [], "rliable's absl log call would have run logging.basicConfig() on the root"


def test_aggregate__the_iqm_without_scipy_s_wrapper_is_rliable_s_to_the_bit():
    from rliable import metrics

    from wfbench.analysis.aggregate import _iqm

    iqm, rng = _iqm(), np.random.default_rng(7)
    shapes = [(int(rng.integers(1, 60)), int(rng.integers(1, 9))) for _ in range(300)]
    mats = [rng.random(s) for s in shapes] + [np.round(rng.random((50, 8)), 1) for _ in range(50)]  # ties too
    mats += [np.array([[0.5, np.nan], [0.2, 0.1]]), np.array([[np.inf, 0.3]])]
    for m in mats:
        assert np.array_equal(iqm(m), metrics.aggregate_iqm(m), equal_nan=True), m.shape


def test_aggregate__intervals_are_those_of_rliable_s_own_metric_functions():
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).parents[2] / "benchmarks" / "aggregate_speed.py"
    spec = importlib.util.spec_from_file_location("aggregate_speed", path)
    bench = importlib.util.module_from_spec(spec)
    sys.modules["aggregate_speed"] = bench
    spec.loader.exec_module(bench)
    s = _scores()
    theirs = bench.rliable_table(s, seed=3, reps=200)
    t = aggregate(s, seed=3, reps=200, profile_reps=10).table.set_index("policy")
    cols = [*STATISTICS, *(f"{k}_low" for k in STATISTICS), *(f"{k}_high" for k in STATISTICS)]
    for name, values in theirs.items():
        assert np.array_equal(t.loc[name, cols].to_numpy(dtype=float), values), name
