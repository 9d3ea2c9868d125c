"""The trace's draws against the distributions docs/model.md gives them.

The reference implementation replays the compiled core's own trace, so the differential
test cannot see a wrong draw: these tests check the distributions themselves, with
tolerances of several standard deviations (each test uses fixed seeds, so it is
deterministic; the margin keeps it valid if the draws are reordered).
"""

import math

import numpy as np
import pytest

from wfbench import ScenarioConfig, Simulator, trace


@pytest.mark.parametrize("scenario", ["paper-64", "small", "table2-g32-f50-s25"])
def test_trace__episode_starts_with_the_configured_entities(scenario):
    config = ScenarioConfig.preset(scenario)
    obs = Simulator(config, [0, 1]).reset()
    assert (obs["facility_mask"].sum(axis=1) == config.initial_facilities).all(), (
        f"{scenario}: active facilities at t=0 {obs['facility_mask'].sum(axis=1)} != initial_facilities "
        f"{config.initial_facilities}")
    assert (obs["personnel_mask"].sum(axis=1) == config.initial_personnel).all(), (
        f"{scenario}: people at t=0 {obs['personnel_mask'].sum(axis=1)} != initial_personnel "
        f"{config.initial_personnel}")


def test_trace__no_arrival_at_step_0():
    # two arrivals per step on average: an arrival at step 0 would show in almost every seed
    config = ScenarioConfig(horizon=30, churn_interval=0.5)
    for seed in range(20):
        arrivals = trace(config, seed).arr_t[0]
        assert arrivals.min() >= 1, f"seed {seed}: an arrival at step 0; arrivals happen at steps 1..horizon-1"


def test_trace__lifetimes_are_exponential_with_mean_initial_facilities_times_churn_interval():
    config = ScenarioConfig(initial_facilities=5, churn_interval=20.0, horizon=2000)
    mean = 5 * 20.0
    # a lifetime is ceil(Exp(mean)): E[ceil X] = sum_k P(X > k) = 1 / (1 - exp(-1 / mean))
    want = 1.0 / (1.0 - math.exp(-1.0 / mean))
    traces = [trace(config, s) for s in range(40)]
    for name, values in (("initial", np.concatenate([tr.fac0_leave[0] for tr in traces])),
                         ("arrival", np.concatenate([tr.arr_leave[0] - tr.arr_t[0] for tr in traces]))):
        se = mean / math.sqrt(len(values))
        assert values.min() >= 1, f"{name} facilities: a lifetime below 1 step"
        assert abs(values.mean() - want) < 5 * se, (
            f"{name} facilities: mean lifetime {values.mean():.1f} over {len(values)}, expected {want:.1f} "
            "(exponential of mean initial_facilities * churn_interval, rounded up)")


def test_trace__cells_are_uniform_over_the_whole_grid():
    config = ScenarioConfig(grid_width=5, grid_height=3, horizon=400, churn_interval=2.0)
    traces = [trace(config, s) for s in range(10)]
    for name, xs, ys in (
        ("initial facility", [t.fac0_x for t in traces], [t.fac0_y for t in traces]),
        ("home", [t.per0_x for t in traces], [t.per0_y for t in traces]),
        ("arrival", [t.arr_x for t in traces], [t.arr_y for t in traces]),
    ):
        x, y = np.concatenate([a.ravel() for a in xs]), np.concatenate([a.ravel() for a in ys])
        assert sorted(set(x.tolist())) == list(range(5)), f"{name} columns {sorted(set(x.tolist()))}: expected 0..4"
        assert sorted(set(y.tolist())) == list(range(3)), f"{name} rows {sorted(set(y.tolist()))}: expected 0..2"


def test_trace__initial_levels_follow_level_probs():
    config = ScenarioConfig(level_probs=(0.6, 0.3, 0.1))
    levels = np.concatenate([trace(config, s).per0_level[0] for s in range(60)])  # 3000 draws
    share = np.bincount(levels, minlength=3) / len(levels)
    np.testing.assert_allclose(share, [0.6, 0.3, 0.1], atol=0.045,  # 5 standard deviations
                               err_msg=f"initial level shares {share}, expected level_probs (0.6, 0.3, 0.1)")
