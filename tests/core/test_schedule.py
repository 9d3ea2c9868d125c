"""Rate schedules by hand, and the trace's arrivals against the churn schedule they follow.

The reference implementation (tests/core/reference.py) reads its failure hazard from
``RateSchedule.multipliers`` too, so the differential test cannot see a change to a
schedule: the values here are worked out from the formulas of wfbench/core/schedule.py's
docstring with ``math``, not with the class under test.
"""

import math

import numpy as np
import pytest

from wfbench import RateSchedule, ScenarioConfig, trace


def seasonal(t, amplitude, period, phase):
    return 1.0 + amplitude * math.sin(2.0 * math.pi * (t / period + phase))


def test_schedule__seasonal_peaks_a_quarter_period_in_and_repeats_every_period():
    m = RateSchedule(kind="seasonal", amplitude=0.5, period=40.0).multipliers(80)
    # sin is 0, 1, 0, -1, 0 at the quarter periods: 1, 1.5, 1, 0.5, 1
    for t, want in [(0, 1.0), (10, 1.5), (20, 1.0), (30, 0.5), (40, 1.0), (50, 1.5), (70, 0.5), (80, 1.0)]:
        assert m[t] == pytest.approx(want, abs=1e-12), (
            f"seasonal multiplier at t={t} is {m[t]}, expected {want} = 1 + 0.5 sin(2 pi t / 40)")
    assert m.shape == (81,), "one multiplier per step 0..horizon"


@pytest.mark.parametrize(("amplitude", "period", "phase"), [(0.3, 17.0, 0.0), (0.9, 200.0, 0.25), (0.5, 7.5, 0.6)])
def test_schedule__seasonal_follows_its_formula(amplitude, period, phase):
    m = RateSchedule(kind="seasonal", amplitude=amplitude, period=period, phase=phase).multipliers(300)
    want = [seasonal(t, amplitude, period, phase) for t in range(301)]
    np.testing.assert_allclose(m, want, rtol=0, atol=1e-12,
                               err_msg="m(t) = 1 + amplitude sin(2 pi (t / period + phase)) (wfbench/core/schedule.py)")


def test_schedule__seasonal_default_period_is_200_steps():
    # the dataclass default: a scenario file that gives no period gets 200 steps
    m = RateSchedule(kind="seasonal", amplitude=0.5).multipliers(400)
    assert (m[50], m[150], m[200], m[250]) == pytest.approx((1.5, 0.5, 1.0, 1.5), abs=1e-12), (
        "a seasonal schedule without a period must peak at t = 50 and repeat every 200 steps")


def test_schedule__seasonal_amplitude_stays_below_1():
    # amplitude 1 would stop the process at the trough (a zero rate); the docstring allows [0, 1)
    with pytest.raises(ValueError, match="amplitude must be in"):
        RateSchedule(kind="seasonal", amplitude=1.0)
    assert RateSchedule(kind="seasonal", amplitude=0.99).multipliers(200).min() > 0


def test_schedule__drift_is_linear_from_start_at_0_to_end_at_the_horizon():
    m = RateSchedule(kind="drift", start=0.5, end=2.5).multipliers(8)
    np.testing.assert_allclose(m, [0.5 + 2.0 * t / 8 for t in range(9)], rtol=0, atol=1e-12)


def test_schedule__piecewise_value_holds_from_its_time_to_the_next():
    m = RateSchedule(kind="piecewise", times=(0, 3, 7), values=(2.0, 0.5, 4.0)).multipliers(9)
    assert m.tolist() == [2.0, 2.0, 2.0, 0.5, 0.5, 0.5, 0.5, 4.0, 4.0, 4.0]
    assert RateSchedule().multipliers(4).tolist() == [1.0] * 5, "constant: 1 at every step"


def test_trace__arrivals_follow_the_seasonal_churn_schedule():
    """Arrivals per step are Poisson with mean churn_schedule(t) / churn_interval (docs/model.md, the trace)."""
    period, amplitude, horizon = 100.0, 0.9, 20_000
    config = ScenarioConfig(horizon=horizon, churn_interval=2.0,
                            churn_schedule=RateSchedule(kind="seasonal", amplitude=amplitude, period=period))
    arrivals = trace(config, 3).arr_t[0]
    assert arrivals.min() >= 1 and arrivals.max() <= horizon - 1, "arrivals happen at steps 1..horizon-1"
    # ten phase bins of 10 steps: observed counts against the expected sum of the rate over the bin's steps
    observed = np.bincount((arrivals % 100) // 10, minlength=10)
    expected = np.zeros(10)
    for t in range(1, horizon):
        expected[(t % 100) // 10] += seasonal(t, amplitude, period, 0.0) / 2.0
    z = (observed - expected) / np.sqrt(expected)
    assert np.abs(z).max() < 5, (
        f"arrivals per phase bin {observed.tolist()} are not Poisson around {np.round(expected).tolist()}: "
        "the trace must draw arrivals at rate churn_schedule(t) / churn_interval")
