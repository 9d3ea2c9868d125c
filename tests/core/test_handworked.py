"""One facility, one person, failures at fixed steps, every visit fixes: metrics by hand.

Facility at (0, 0), the person's home at (3, 0), speed 1, service 2, window 10. Failure
clocks are forced by a piecewise rate that is ~0 except at steps 5 and 12, where it is
huge. The person is dispatched whenever the request is open.

Timeline: fail at 5; travel 5, 6, 7 (arrives at 7); service 8, 9 (repaired at 9);
return 10, 11, 12. Fail at 12; the returning person (at x = 2 at the start of 12) is sent
back: travel 12, 13 (arrives); service 14, 15 (repaired at 15); return 16, 17, 18.
Down steps: 5-9 and 12-15. Work steps: 5-18.
"""

import numpy as np
import pytest

from wfbench import RateSchedule, ScenarioConfig, Simulator

HUGE, TINY = 1e12, 1e-12
DOWN = set(range(5, 10)) | set(range(12, 16))
WORK = set(range(5, 19))


@pytest.fixture
def run():
    config = ScenarioConfig(
        grid_width=8, grid_height=8, max_facilities=1, max_personnel=2, initial_facilities=1, initial_personnel=1,
        min_personnel=1, horizon=20, request_interval=1.0, churn_interval=1e9, base_fix_rate=1.0,
        level_multipliers=(1.0, 1.0, 1.0), level_salaries=(1.0, 1.0, 1.0), speed=1.0, service_time=2, window=10,
        request_schedule=RateSchedule(kind="piecewise", times=(0, 5, 6, 12, 13), values=(TINY, HUGE, TINY, HUGE, TINY)),
    )
    sim = Simulator(config, [0])
    sim.trace.fac0_x[0, 0], sim.trace.fac0_y[0, 0] = 0, 0
    sim.trace.per0_x[0, 0], sim.trace.per0_y[0, 0] = 3, 0
    obs = sim.reset()
    for _ in range(config.horizon):
        dispatch = np.where(obs["requesting"][0] == 1, 0, 2)[None]
        sim.step({"dispatch": dispatch, "workforce": np.zeros(1, int), "positioning": np.zeros((1, 2, 1))})
        obs = sim.observe()
    return sim


def by_hand(t, steps):
    seen = min(10, t + 1)
    return len([s for s in steps if t - 10 < s <= t]) / seen


def test_downtime_and_utilization_by_hand(run):
    series = run.state.series[0]
    for t in range(20):
        assert series[t, 2] == pytest.approx(by_hand(t, DOWN)), f"downtime at step {t}"
        assert series[t, 1] == pytest.approx(by_hand(t, WORK)), f"utilization at step {t}"
    # spot values worked out on paper
    assert series[9, 2] == pytest.approx(0.5) and series[9, 1] == pytest.approx(0.5)
    assert series[19, 2] == pytest.approx(0.4) and series[19, 1] == pytest.approx(0.9)


def test_workforce_cost_and_nsw_by_hand(run):
    series = run.state.series[0]
    assert (series[:, 0] == 1.0).all()
    t = 19
    u_wc = 1 - 1.0 / 2.0
    u_pur = 1 - max(0.0, abs(0.9 - 0.75) - 0.05) / 0.70
    u_afd = 1 - 0.4
    assert series[t, 3] == pytest.approx((u_wc * u_pur * u_afd) ** (1 / 3), rel=1e-6)


def test_counts(run):
    c = run.counters(0)
    assert (c["requests"][()], c["visits"][()], c["repairs"][()]) == (2, 2, 2)
