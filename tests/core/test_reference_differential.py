"""The compiled core and the readable reference (tests/core/reference.py) give identical runs."""

import numpy as np
import pytest

from wfbench import ScenarioConfig, Simulator
from wfbench.core.schedule import RateSchedule
from wfbench.core.state import EMPTY

from .reference import ReferenceEnv


def random_config(rng: np.random.Generator) -> ScenarioConfig:
    M = int(rng.integers(1, 7))
    N = int(rng.integers(1, 7))
    sched = [RateSchedule(), RateSchedule(kind="seasonal", amplitude=0.5, period=17.0),
             RateSchedule(kind="drift", start=0.5, end=2.0)][int(rng.integers(0, 3))]
    return ScenarioConfig(
        grid_width=int(rng.integers(1, 10)), grid_height=int(rng.integers(1, 10)),
        max_facilities=M, max_personnel=N,
        initial_facilities=int(rng.integers(0, M + 1)), initial_personnel=(n0 := int(rng.integers(0, N + 1))),
        min_personnel=int(rng.integers(0, n0 + 1)), horizon=int(rng.integers(5, 70)),
        request_interval=float(rng.uniform(2, 30)), churn_interval=float(rng.uniform(3, 40)),
        base_fix_rate=float(rng.uniform(0.2, 0.8)), speed=float(rng.choice([0.5, 1.0, 1.5, 3.0])),
        service_time=int(rng.integers(1, 5)), hire_delay=int(rng.integers(1, 6)), fire_delay=int(rng.integers(0, 6)),
        window=int(rng.integers(1, 12)), heat_sigma=float(rng.uniform(0.5, 4)),
        placement=str(rng.choice(["argmax", "sample"])), request_schedule=sched,
    )


def random_actions(rng, M, N):
    dispatch = np.full(M, N)
    pick = rng.random(M) < 0.5
    dispatch[pick] = rng.integers(0, N + 1, size=int(pick.sum()))
    workforce = int(rng.integers(0, 7)) if rng.random() < 0.2 else 0
    positioning = rng.random((2, M)) * (rng.random((2, M)) < 0.8)
    return dispatch, workforce, positioning


@pytest.mark.parametrize("case", range(120))
def test_core_matches_reference(case):
    rng = np.random.default_rng(1000 + case)
    config = random_config(rng)
    seed = int(rng.integers(0, 10_000))
    sim = Simulator(config, [seed])
    sim.reset()
    ref = ReferenceEnv(config, sim.trace)
    M, N = config.max_facilities, config.max_personnel
    S = sim.state
    for t in range(config.horizon):
        d, w, p = random_actions(rng, M, N)
        sim.step({"dispatch": d[None], "workforce": np.array([w]), "positioning": p[None]})
        ref.step(d, w, p)
        got = tuple(float(x) for x in S.last[0, :4])
        assert got == ref.metrics[-1], f"case {case} step {t}: metrics {got} != reference {ref.metrics[-1]}"
        for i, per in enumerate(ref.per):
            assert S.per_status[0, i] == per.status, f"case {case} step {t}: status of person {i}"
            if per.status != EMPTY:
                assert (S.per_x[0, i], S.per_y[0, i], S.per_target[0, i]) == (per.x, per.y, per.target), (
                    f"case {case} step {t}: person {i}")
                assert (S.per_hx[0, i], S.per_hy[0, i], S.per_leave[0, i]) == (per.hx, per.hy, per.leave)
        for f, fac in enumerate(ref.fac):
            assert bool(S.fac_active[0, f]) == fac.active, f"case {case} step {t}: facility {f} active"
            if fac.active:
                assert (bool(S.fac_down[0, f]), S.fac_assigned[0, f]) == (fac.down, fac.assigned), (
                    f"case {case} step {t}: facility {f}")
    counters = sim.counters(0)
    names = dict(zip(ref.counts, counters, strict=True))
    assert [int(counters[names[k]]) for k in ref.counts] == list(ref.counts.values())
