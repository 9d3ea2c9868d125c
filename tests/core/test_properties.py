"""Invariants over random configs and random actions (hypothesis)."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wfbench import ScenarioConfig, Simulator
from wfbench.core.state import EMPTY, ONBOARDING, SERVICING, TO_FACILITY


@st.composite
def configs(draw):
    M = draw(st.integers(1, 8))
    N = draw(st.integers(1, 8))
    n0 = draw(st.integers(0, N))
    return ScenarioConfig(
        grid_width=draw(st.integers(1, 12)), grid_height=draw(st.integers(1, 12)), max_facilities=M,
        max_personnel=N, initial_facilities=draw(st.integers(0, M)), initial_personnel=n0,
        min_personnel=draw(st.integers(0, n0)), horizon=draw(st.integers(1, 60)),
        request_interval=draw(st.floats(1.0, 40.0)), churn_interval=draw(st.floats(2.0, 60.0)),
        speed=draw(st.sampled_from([0.5, 1.0, 2.5])), service_time=draw(st.integers(1, 4)),
        hire_delay=draw(st.integers(1, 8)), fire_delay=draw(st.integers(0, 8)), window=draw(st.integers(1, 15)),
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(config=configs(), seed=st.integers(0, 2**31 - 1), action_seed=st.integers(0, 2**31 - 1))
def test_invariants_hold_under_random_actions(config, seed, action_seed):
    rng = np.random.default_rng(action_seed)
    sim = Simulator(config, [seed])
    sim.reset()
    S = sim.state
    M, N = config.max_facilities, config.max_personnel
    hired_at: dict[int, int] = {}
    while not sim.done:
        t = sim.t
        d = rng.integers(0, N + 1, size=(1, M))
        w = rng.integers(0, 7, size=1)
        p = rng.random((1, 2, M))
        hires_before = int(S.counters[0, 6])
        empty_before = set(np.flatnonzero(S.per_status[0] == EMPTY))
        sim.step({"dispatch": d, "workforce": w, "positioning": p})
        if int(S.counters[0, 6]) > hires_before:
            slot = min(empty_before)
            hired_at[slot] = t
        status, target = S.per_status[0], S.per_target[0]
        # nobody is in two places: a person's job and the facility's assignee agree
        for person in range(N):
            if status[person] in (TO_FACILITY, SERVICING):
                f = target[person]
                assert S.fac_active[0, f] and S.fac_down[0, f] and S.fac_assigned[0, f] == person
            else:
                assert target[person] == -1
        # at most one person per open request
        assigned = S.fac_assigned[0][S.fac_assigned[0] >= 0]
        assert len(set(assigned.tolist())) == len(assigned)
        for f in np.flatnonzero(S.fac_assigned[0] >= 0):
            assert S.fac_down[0, f] and target[S.fac_assigned[0, f]] == f
        # metrics within [0, 1]
        wc, pur, afd, nsw = S.last[0, :4]
        assert 0.0 <= pur <= 1.0 and 0.0 <= afd <= 1.0 and 0.0 <= nsw <= 1.0
        assert 0.0 <= wc <= config.max_workforce_cost
        # headcount within bounds
        head = int((status != EMPTY).sum())
        retained = int(((status != EMPTY) & (S.per_leave[0] < 0)).sum())
        assert head <= N
        assert retained >= min(config.min_personnel, config.initial_personnel)
        # a hire works only after its delay
        for slot, t0 in hired_at.items():
            if sim.t < t0 + config.hire_delay and status[slot] != EMPTY:
                assert status[slot] == ONBOARDING, f"hire in slot {slot} at {t0} active before its delay"
