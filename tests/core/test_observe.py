"""Observations against values computed without the compiled core.

The differential test (tests/core/test_reference_differential.py) compares the core's state and
metrics with the readable reference, but never the observation an agent sees: a change to
a feature (its rolling window, a mask, a global) went unnoticed. Here every observation
array is rebuilt from the reference's entities by the rules of docs/model.md
("Observations and actions"), and one rolling feature is worked out by hand.
"""

import numpy as np
import pytest

from wfbench import RateSchedule, ScenarioConfig, Simulator
from wfbench.core.observation_v2 import WORLD_FEATURES
from wfbench.core.observe import FACILITY_FEATURES, GLOBAL_FEATURES, PERSONNEL_FEATURES

from .reference import EMPTY, IDLE, ONBOARDING, RETURNING, SERVICING, TO_FACILITY, ReferenceEnv
from .test_reference_differential import random_actions, random_config

HUGE, TINY = 1e12, 1e-12
# the hand-worked timeline of tests/core/test_handworked.py: down steps and work steps of its one facility and person
DOWN = set(range(5, 10)) | set(range(12, 16))
WORK = set(range(5, 19))


def rolling(steps, t, since, window):
    """Share of the steps in ``steps`` among the last ``window`` steps before ``t`` (those since ``since``)."""
    seen = max(1, min(window, t - since))
    return len([s for s in steps if t - window <= s < t and s >= since]) / seen


def handworked_run(window):
    """Observations after every step of the hand-worked episode (one facility, one person), with ``window``."""
    config = ScenarioConfig(
        grid_width=8, grid_height=8, max_facilities=1, max_personnel=2, initial_facilities=1, initial_personnel=1,
        min_personnel=1, horizon=20, request_interval=1.0, churn_interval=1e9, base_fix_rate=1.0,
        level_multipliers=(1.0, 1.0, 1.0), level_salaries=(1.0, 1.0, 1.0), speed=1.0, service_time=2, window=window,
        request_schedule=RateSchedule(kind="piecewise", times=(0, 5, 6, 12, 13), values=(TINY, HUGE, TINY, HUGE, TINY)),
    )
    sim = Simulator(config, [0])
    sim.trace.fac0_x[0, 0], sim.trace.fac0_y[0, 0] = 0, 0
    sim.trace.per0_x[0, 0], sim.trace.per0_y[0, 0] = 3, 0
    obs = sim.reset()
    seen = [{k: v.copy() for k, v in obs.items()}]
    for _ in range(config.horizon - 1):
        dispatch = np.where(obs["requesting"][0] == 1, 0, 2)[None]
        sim.step({"dispatch": dispatch, "workforce": np.zeros(1, int), "positioning": np.zeros((1, 2, 1))})
        obs = sim.observe()
        seen.append({k: v.copy() for k, v in obs.items()})
    return seen


@pytest.mark.parametrize("window", [3, 10])
def test_observe__utilization_window_is_config_window(window):
    util = PERSONNEL_FEATURES.index("utilization")
    for t, obs in enumerate(handworked_run(window)):
        expected = np.float32(rolling(WORK, t, 0, window))
        assert obs["personnel"][0, 0, util] == expected, (
            f"window {window}, step {t}: personnel utilization feature {obs['personnel'][0, 0, util]} != {expected} "
            "(work steps among the last `window` steps / min(window, steps since onboarded)); "
            "wfbench/core/observe.py must roll over ScenarioConfig.window")


@pytest.mark.parametrize("window", [3, 10])
def test_observe__downtime_window_is_config_window(window):
    down = FACILITY_FEATURES.index("downtime")
    for t, obs in enumerate(handworked_run(window)):
        expected = np.float32(rolling(DOWN, t, 0, window))
        assert obs["facilities"][0, 0, down] == expected, (
            f"window {window}, step {t}: facility downtime feature {obs['facilities'][0, 0, down]} != {expected}; "
            "wfbench/core/observe.py must roll over ScenarioConfig.window")


def reference_observation(ref: ReferenceEnv, config: ScenarioConfig) -> dict[str, np.ndarray]:
    """Every observation array from the reference's entities, by docs/model.md "Observations and actions"."""
    M, N, W, t = config.max_facilities, config.max_personnel, config.window, ref.t
    fac = np.zeros((M, len(FACILITY_FEATURES)), np.float32)
    per = np.zeros((N, len(PERSONNEL_FEATURES)), np.float32)
    o = {name: np.zeros(n, np.int8) for name, n in (
        ("facility_mask", M), ("personnel_mask", N), ("personnel_status", N), ("under_notice", N),
        ("dispatchable", N), ("requesting", M))}
    for f, x in enumerate(ref.fac):
        if not x.active:
            fac[f, FACILITY_FEATURES.index("assigned_person")] = -1
            continue
        down_steps = [s for s, down in x.history if down]
        fac[f] = (x.x, x.y, not x.down, x.down, x.assigned >= 0, x.assigned, rolling(down_steps, t, x.since, W))
        o["facility_mask"][f] = 1
        o["requesting"][f] = x.down and x.assigned < 0
    levels = [0, 0, 0]
    onboarding = notice = kept = 0
    releasable = [False, False, False]
    for p, x in enumerate(ref.per):
        o["personnel_status"][p] = x.status
        if x.status == EMPTY:
            per[p, PERSONNEL_FEATURES.index("assigned_facility")] = -1
            continue
        work_steps = [s for s, worked in x.history if worked]
        util = rolling(work_steps, t, x.since, W) if x.status >= IDLE and t > x.since else 0.0
        per[p] = (x.hx, x.hy, x.x, x.y, x.level, x.status in (TO_FACILITY, SERVICING), x.target,
                  x.status == TO_FACILITY, util)
        o["personnel_mask"][p] = 1
        o["under_notice"][p] = x.leave >= 0
        o["dispatchable"][p] = x.status in (IDLE, RETURNING) and x.leave < 0
        levels[x.level] += 1
        onboarding += x.status == ONBOARDING
        notice += x.leave >= 0
        kept += x.leave < 0
        releasable[x.level] |= x.status >= IDLE and x.leave < 0
    wc, pur, afd, nsw = ref.metrics[-1] if ref.metrics else (0.0, 0.0, 0.0, 0.0)
    head = int(o["personnel_mask"].sum())
    g = dict(time_fraction=t / config.horizon, headcount=head / N, onboarding=onboarding / N, under_notice=notice / N,
             novices=levels[0] / N, mids=levels[1] / N, experts=levels[2] / N,
             workforce_cost=wc / config.max_workforce_cost, utilization=pur, downtime=afd, nsw=nsw,
             active_facilities=int(o["facility_mask"].sum()) / M)
    free_slot = head < N
    can_let_go = kept > config.min_personnel
    wm = [1, free_slot, free_slot, free_slot] + [can_let_go and r for r in releasable]
    dm = np.zeros((M, N + 1), np.int8)
    dm[:, :N] = o["requesting"][:, None] & o["dispatchable"][None, :]
    dm[:, N] = 1
    o.update(facilities=fac, personnel=per, globals=np.array([g[k] for k in GLOBAL_FEATURES], np.float32),
             dispatch_mask=dm, workforce_mask=np.array(wm, np.int8), t=np.int64(t), world=world_row(config, t))
    return o


def world_row(config: ScenarioConfig, t: int) -> np.ndarray:
    """The ``world`` key, by docs/policies.md "Observation version 2": the config's public fields in its own units."""
    c, step = config, min(t, config.horizon)
    values = dict(
        speed=c.speed, grid_width=c.grid_width, grid_height=c.grid_height, heat_sigma=c.heat_sigma,
        horizon=c.horizon, window=c.window, service_time=c.service_time, hire_delay=c.hire_delay,
        notice_delay=c.fire_delay, request_interval=c.request_interval, churn_interval=c.churn_interval,
        request_multiplier=c.request_schedule.multipliers(c.horizon)[step],
        churn_multiplier=c.churn_schedule.multipliers(c.horizon)[step],
        fix_novice=c.base_fix_rate * c.level_multipliers[0], fix_mid=c.base_fix_rate * c.level_multipliers[1],
        fix_expert=c.base_fix_rate * c.level_multipliers[2], salary_novice=c.level_salaries[0],
        salary_mid=c.level_salaries[1], salary_expert=c.level_salaries[2], target_utilization=c.target_utilization,
        utilization_tolerance=c.utilization_tolerance, max_facilities=c.max_facilities,
        max_personnel=c.max_personnel, min_personnel=c.min_personnel)
    assert tuple(values) == WORLD_FEATURES, "the reference lists the world's columns in another order"
    return np.array(list(values.values()), dtype=np.float64)


@pytest.mark.parametrize("case", range(40))
def test_observe__every_array_matches_the_reference_entities(case):
    rng = np.random.default_rng(5000 + case)
    config = random_config(rng)
    seed = int(rng.integers(0, 10_000))
    sim = Simulator(config, [seed])
    obs = sim.reset()
    ref = ReferenceEnv(config, sim.trace)
    M, N = config.max_facilities, config.max_personnel
    for step in range(config.horizon):
        expected = reference_observation(ref, config)
        assert set(obs) == set(expected), f"observation keys {sorted(obs)} != {sorted(expected)}"
        for name, want in expected.items():
            np.testing.assert_array_equal(
                obs[name][0], want,
                err_msg=f"case {case}, t={ref.t}: observation {name!r} differs from the reference entities "
                        "(docs/model.md, 'Observations and actions'); fix wfbench/core/observe.py")
        if step == config.horizon - 1:
            break
        d, w, p = random_actions(rng, M, N)
        sim.step({"dispatch": d[None], "workforce": np.array([w]), "positioning": p[None]})
        obs = sim.observe()
        ref.step(d, w, p)
