"""Simulators built from what a policy sees (wfbench.core.belief, issue #43).

- the fork agrees with the observation: re-observing it gives the observation back, and
  every part reconstructed from past observations is the true state's, bit for bit;
- future blindness: two episodes that agree on everything observed up to step T and
  differ afterwards give the same forks at T (and the fork of the true state does not);
- goodness of fit: the forked worlds' arrivals, failures and lifetimes follow the public
  model, and the same tests reject a model that ignores the schedules' multipliers.
"""

import math

import numpy as np
import pytest
from scipy import stats

from wfbench import ScenarioConfig, Simulator, policies
from wfbench.core.belief import Belief, PublicModel, belief_key, row_key
from wfbench.core.fork import fork as true_fork
from wfbench.core.fork import state_equal
from wfbench.core.schedule import RateSchedule
from wfbench.core.state import EMPTY, ONBOARDING
from wfbench.core.trace import NEVER, trace

from .play import random_actions

SMALL = ScenarioConfig.preset("small").replace(horizon=240)
OBSERVED = ("facilities", "personnel", "facility_mask", "personnel_mask", "personnel_status", "under_notice",
            "dispatchable", "requesting", "globals", "workforce_mask", "dispatch_mask")
NOOP = None


def noop(sim):
    return {"dispatch": np.full((sim.B, sim.M), sim.N, dtype=np.int64), "workforce": np.zeros(sim.B, np.int64),
            "positioning": np.zeros((sim.B, 2, sim.M))}


# -- (c) the fork agrees with the observation -----------------------------------------------------------------------
RECONSTRUCTED_FAC = ("fac_x", "fac_y", "fac_down", "fac_assigned", "fac_since", "fac_ring", "fac_sum")
RECONSTRUCTED_PER = ("per_status", "per_level", "per_hx", "per_hy", "per_x", "per_y", "per_target", "per_timer",
                     "per_since", "per_ring", "per_sum")


@pytest.mark.parametrize("config", [SMALL, SMALL.replace(name="small-ns", hire_delay=1, fire_delay=0,
                                                            request_schedule=RateSchedule(kind="seasonal",
                                                                                          amplitude=0.5))],
                         ids=["small", "short-delays"])
def test_the_fork_reobserves_the_observation_and_holds_the_true_history(config):
    seeds = [3, 8, 1011]
    sim = Simulator(config, seeds)
    obs = sim.reset()
    bel = Belief(config)
    bel.reset(seeds)
    rows = bel.simulator(6)
    envs, ks = np.repeat(np.arange(3), 2), np.tile(np.arange(2), 3)
    rng = np.random.default_rng(7)
    events = {"notices": 0, "servicing": 0}
    for _ in range(config.horizon - 1):
        bel.update(obs)
        bel.sample_into(rows, envs, ks)
        mine = rows.observe()
        for key in OBSERVED:
            assert np.array_equal(mine[key], obs[key][envs]), (int(sim.t), key)
        S, F = sim.state, rows.state
        for i, b in enumerate(envs):
            act = S.fac_active[b]
            for name in RECONSTRUCTED_FAC:
                assert np.array_equal(getattr(S, name)[b][act], getattr(F, name)[i][act]), (int(sim.t), name)
            emp = S.per_status[b] != EMPTY
            for name in RECONSTRUCTED_PER:
                assert np.array_equal(getattr(S, name)[b][emp], getattr(F, name)[i][emp]), (int(sim.t), name)
            onb = S.per_status[b] == ONBOARDING
            assert np.array_equal(S.per_ready[b][onb], F.per_ready[i][onb])
            assert np.array_equal(S.per_leave[b], F.per_leave[i])
        events["notices"] += int((S.per_leave >= 0).sum())
        events["servicing"] += int((S.per_status == 4).sum())
        # hire and let go now and then: the history then has every kind of event
        sim.step(random_actions(sim.B, sim.M, sim.N, obs, rng, hire_rate=0.1))
        obs = sim.observe()
    events["hires"] = int(sim.counters()["hires"].sum())
    assert min(events.values()) > 0, events  # the history had hires, notices and visits to reconstruct


def test_the_unobserved_parts_are_drawn_not_copied():
    """The fork's keys, clocks, lifetimes and arrivals are the belief's own; two samples differ."""
    sim = Simulator(SMALL, [5])
    obs = sim.reset()
    bel = Belief(SMALL)
    bel.reset([5])
    pol = policies.get("heuristic")
    pol.reset([5])
    for _ in range(40):
        bel.update(obs)
        sim.step(pol.act(obs))
        obs = sim.observe()
    bel.update(obs)
    f = bel.sample(copies=2)
    assert f.trace.key[0] == row_key(belief_key(5), 40, 0) != sim.trace.key[0]
    assert f.trace.key[0] != f.trace.key[1]
    on = sim.state.fac_active[0] & ~sim.state.fac_down[0]
    assert not np.array_equal(f.state.fac_hazard[0][on], sim.state.fac_hazard[0][on])
    assert not np.array_equal(f.state.fac_hazard[0][on], f.state.fac_hazard[1][on])
    assert (f.state.fac_leave[:, sim.state.fac_active[0]] > 40).all()
    arr = f.trace.arr_t[0]
    assert (arr[arr < NEVER] > 40).all()


def test_bad_use_is_refused_in_one_line():
    sim = Simulator(SMALL, [1])
    obs = sim.reset()
    bel = Belief(SMALL)
    with pytest.raises(RuntimeError, match="reset"):
        bel.update(obs)
    bel.reset([1])
    sim.step(noop(sim))
    with pytest.raises(ValueError, match="first observation is at step 1"):
        bel.update(sim.observe())
    bel.reset([1])
    bel.update(sim.reset())
    sim.step(noop(sim))
    sim.step(noop(sim))
    with pytest.raises(ValueError, match="jumped to step 2"):
        bel.update(sim.observe())
    other = Belief(SMALL.replace(service_time=5))
    other.reset([1])
    with pytest.raises(ValueError, match="service_time = 3"):
        other.update(sim.reset())
    with pytest.raises(ValueError, match="rows"):
        bel.simulator(0)


# -- (a) future blindness ---------------------------------------------------------------------------------------------
def other_future(sim: Simulator, seed: int) -> Simulator:
    """The true episode at its step T with every future draw replaced by those of ``seed`` (the past kept).

    The key (failure clocks, repair outcomes, placements after T) and the arrivals after T
    are ``seed``'s trace's; the remaining clocks of operational facilities and the remaining
    lifetimes of active ones are redrawn. What was observed up to T stays as it was.
    """
    T = sim.t
    twin = true_fork(sim, keep_series=False)
    other = trace(sim.config, seed)
    twin.trace.key[:] = other.key[0]
    tr = twin.trace
    future = other.arr_t[0] > T
    n = int(future.sum())
    keep = tr.arr_t[0] <= T
    k = int(keep.sum())
    for name in ("arr_t", "arr_x", "arr_y", "arr_leave"):
        a = getattr(tr, name)
        fill = NEVER if name in ("arr_t", "arr_leave") else 0
        row = np.concatenate([a[0][keep], getattr(other, name)[0][future]])[: a.shape[1]]
        a[0, :] = fill
        a[0, : row.shape[0]] = row
    twin.state.arr_ptr[0] = k
    rng = np.random.default_rng(seed)
    S = twin.state
    on = S.fac_active[0]
    S.fac_hazard[0][on & ~S.fac_down[0]] = rng.exponential(size=int((on & ~S.fac_down[0]).sum()))
    mean = sim.config.initial_facilities * sim.config.churn_interval
    S.fac_leave[0][on] = T + np.maximum(1, np.ceil(rng.exponential(mean, size=int(on.sum())))).astype(np.int64)
    assert n > 0
    return twin


def test_two_episodes_that_agree_up_to_T_give_the_same_forks_at_T():
    seed, T = 1003, 70
    sim = Simulator(SMALL, [seed])
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset([seed])
    bel = Belief(SMALL)
    bel.reset([seed])
    for _ in range(T):
        bel.update(obs)
        sim.step(pol.act(obs))
        obs = sim.observe()
    twin = other_future(sim, 1017)
    seen_a, seen_b = sim.observe(), {k: v.copy() for k, v in twin.observe().items()}
    seen_a = {k: v.copy() for k, v in seen_a.items()}
    for key in OBSERVED:
        assert np.array_equal(seen_a[key], seen_b[key]), key  # the same past, as observed
    bel_b = Belief(SMALL)
    bel_b.reset_keys(bel.H.key.copy())
    for name, a in bel.H._asdict().items():  # the history of steps 0..T-1 is common to both episodes
        getattr(bel_b.H, name)[...] = a
    bel.update(seen_a)
    bel_b.update(seen_b)
    fa, fb = bel.sample(copies=3, steps=100), bel_b.sample(copies=3, steps=100)
    assert state_equal(fa, fb) == []
    assert all(np.array_equal(x, y) for x, y in zip(fa.trace, fb.trace, strict=True))
    # the negative control: forks of the true states differ, so a lookahead that read them would tell A from B
    ta, tb = true_fork(sim, copies=1), true_fork(twin, copies=1)
    assert state_equal(ta, tb) != []
    # and the two futures really differ: the same actions from T on give other observations
    for _ in range(60):
        a = pol.act(sim.observe())
        sim.step(a)
        twin.step(a)
    assert not np.array_equal(sim.observe()["facilities"], twin.observe()["facilities"])


# -- (b) goodness of fit -----------------------------------------------------------------------------------------------
NONSTATIONARY = ScenarioConfig.preset("nonstationary")
FLAT = dict(request_schedule=RateSchedule(), churn_schedule=RateSchedule())


def sampled(bel: Belief, rows: int, chunk: int = 250, steps: int | None = None):
    """``rows`` samples of environment 0 at its last step, in chunks of a reused fork: (state, trace) copies."""
    sim = bel.simulator(min(rows, chunk))
    out = []
    for lo in range(0, rows, chunk):
        n = min(chunk, rows - lo)
        bel.sample_into(sim, np.zeros(n, np.int64), np.arange(lo, lo + n, dtype=np.int64), steps)
        out.append(({k: v[:n].copy() for k, v in sim.state._asdict().items()},
                    {k: v[:n].copy() for k, v in sim.trace._asdict().items()}))
    return out


def chi2_p(observed, probs):
    """Pearson's chi-square p-value of counts ``observed`` against cell probabilities ``probs``."""
    observed = np.asarray(observed, dtype=np.float64)
    expected = np.asarray(probs, dtype=np.float64) * observed.sum()
    assert expected.min() >= 5, expected
    return stats.chisquare(observed, expected).pvalue


def belief_at(model_config: ScenarioConfig, truth: ScenarioConfig, seed: int, steps: int) -> Belief:
    """A belief with the model ``model_config`` that watched ``steps`` no-op steps of the world ``truth``."""
    sim = Simulator(truth, [seed])
    obs = sim.reset()
    bel = Belief(model_config)
    bel.reset([seed])
    for _ in range(steps):
        bel.update(obs)
        sim.step(noop(sim))
        obs = sim.observe()
    bel.update(obs)
    return bel


def arrival_pvalues(model_config, truth, t0=100):
    """p-values of the forks' arrival counts (Poisson) and steps (the schedule's shape) under ``truth``'s model."""
    bel = belief_at(model_config, truth, 1020, t0)
    arr = np.concatenate([tr["arr_t"] for _, tr in sampled(bel, 2000)])
    counts = (arr < NEVER).sum(axis=1)
    cum = PublicModel.from_config(truth).churn_cum
    lam = cum[-1] - cum[t0]
    edges = np.arange(int(lam - 2 * math.sqrt(lam)), int(lam + 2 * math.sqrt(lam)) + 1)
    cdf = stats.poisson.cdf(edges, lam)
    probs = np.diff(np.concatenate([[0.0], cdf, [1.0]]))
    binned = np.bincount(np.searchsorted(edges, counts, side="left"), minlength=probs.size)
    p_count = chi2_p(binned, probs)
    steps = arr[arr < NEVER]
    cuts = np.linspace(t0, truth.horizon - 1, 11).astype(int)
    mass = np.diff(cum[cuts]) / (cum[cuts[-1]] - cum[cuts[0]])
    p_time = chi2_p(np.histogram(steps, bins=cuts + 0.5)[0], mass)
    return p_count, p_time


def test_forked_arrivals_follow_the_public_model_and_a_flat_model_is_rejected():
    p_count, p_time = arrival_pvalues(NONSTATIONARY, NONSTATIONARY)
    assert p_count > 1e-3 and p_time > 1e-3, (p_count, p_time)
    wrong = arrival_pvalues(NONSTATIONARY.replace(**FLAT), NONSTATIONARY)
    assert max(wrong) < 1e-6, wrong


def failure_pvalue(model_config, truth, t0=15, horizon=250):
    """p-value of the first failure step of the facilities operational at ``t0`` in forks left alone."""
    bel = belief_at(model_config, truth, 1030, t0)
    firsts = []
    for state, tr in sampled(bel, 300):
        sim = Simulator(model_config, [0] * state["t"].shape[0], keep_series=False, threads=1)
        sim.reset()
        sim.trace = type(sim.trace)(**tr)
        for name, a in state.items():
            if name != "series":
                getattr(sim.state, name)[...] = a
        up = sim.state.fac_active & ~sim.state.fac_down
        first = np.full(up.shape, NEVER)
        for _ in range(horizon):
            sim.step(noop(sim))
            first[up & sim.state.fac_down & (first == NEVER)] = sim.t
        firsts.append(first[up])
    firsts = np.concatenate(firsts)
    lam = np.cumsum(truth.request_schedule.multipliers(truth.horizon) / truth.request_interval)
    cuts = np.array([t0, t0 + 10, t0 + 20, t0 + 35, t0 + 50, t0 + 70, t0 + 100, t0 + 140, t0 + 190, t0 + horizon])
    survive = np.exp(-(lam[cuts] - lam[t0]))
    probs = np.append(-np.diff(survive), survive[-1])
    observed = np.append(np.histogram(firsts[firsts < NEVER], bins=cuts + 0.5)[0], (firsts == NEVER).sum())
    return chi2_p(observed, probs)


def test_forked_failures_follow_the_public_model_and_a_flat_model_is_rejected():
    # no churn (a facility's failures are then not censored by its exit), requests drifting 0.5x -> 3x
    truth = NONSTATIONARY.replace(churn_interval=1e9, request_schedule=RateSchedule(kind="drift", start=0.5, end=3.0))
    assert failure_pvalue(truth, truth) > 1e-3
    assert failure_pvalue(truth.replace(request_schedule=RateSchedule()), truth) < 1e-6


def lifetime_pvalue(model_config, truth, t0=60):
    """p-value of the forks' remaining lifetimes of active facilities and lifetimes of arrivals (geometric)."""
    bel = belief_at(model_config, truth, 1040, t0)
    life = []
    for state, tr in sampled(bel, 400):
        life.append((state["fac_leave"] - t0)[state["fac_active"]])
        ok = tr["arr_t"] < NEVER
        life.append((tr["arr_leave"] - tr["arr_t"])[ok])
    life = np.concatenate(life)
    mean = truth.initial_facilities * truth.churn_interval
    cuts = np.array([0, 100, 300, 600, 1000, 1600, 2500, 4000, 6000])
    cdf = 1.0 - np.exp(-cuts / mean)
    probs = np.append(np.diff(cdf), 1.0 - cdf[-1])
    observed = np.append(np.histogram(life, bins=cuts + 0.5)[0], (life > cuts[-1]).sum())
    return chi2_p(observed, probs)


def test_forked_lifetimes_follow_the_public_model_and_a_wrong_mean_is_rejected():
    assert lifetime_pvalue(NONSTATIONARY, NONSTATIONARY) > 1e-3
    # initial_facilities is not in the observation's world: a model that gets it wrong gets the lifetimes wrong
    assert lifetime_pvalue(NONSTATIONARY.replace(initial_facilities=12), NONSTATIONARY) < 1e-6


def _compiled_rollout():
    from wfbench.policies.lookahead import Rollout

    return Rollout(policies.get("solver-tuned"), K=2, H=30, R=10, scenario=SMALL)


def _network_rollout():
    from wfbench.policies.lookahead.network_rollout import NetworkRollout

    return NetworkRollout(policies.get("scalefree-general"), K=2, H=10, R=10, scenario=SMALL)


def _network_search():
    from wfbench.policies.lookahead.search import NetworkSearch

    return NetworkSearch(policies.get("scalefree-general"), K=2, H=8, R=10, top=3, z=1.0, scenario=SMALL)


@pytest.mark.slow
@pytest.mark.parametrize("make", [_compiled_rollout, _network_rollout, _network_search],
                         ids=["solver-tuned", "scalefree-general", "search-scalefree-general"])
def test_a_rollout_acts_the_same_up_to_T_in_two_episodes_that_differ_after_T(make):
    """The lookahead policy itself: the same actions at every step up to T, and the same candidate scores at T."""
    seed, T = 1004, 40  # T: a decision step (T % R == 0)
    runs = []
    for swap in (False, True):
        sim = Simulator(SMALL, [seed])
        obs = sim.reset()
        pol = make()
        pol.reset([seed])
        actions = []
        for t in range(T + 1):
            if swap and t == T:
                sim = other_future(sim, 1019)
                obs = sim.observe()
            a = pol.act(obs)
            actions.append({k: v.copy() for k, v in a.items()})
            if t < T:
                sim.step(a)
                obs = sim.observe()
        runs.append((sim, pol, actions))
    (sim_a, pol_a, act_a), (sim_b, pol_b, act_b) = runs
    for t, (x, y) in enumerate(zip(act_a, act_b, strict=True)):
        for k in x:
            assert np.array_equal(x[k], y[k]), (t, k)
    assert np.isfinite(pol_a.last_scores).sum() >= 2  # T was a decision with several candidates
    assert np.array_equal(pol_a.last_scores, pol_b.last_scores, equal_nan=True)
    # the episodes do part after T
    for _ in range(60):
        a = pol_a.act(sim_a.observe())
        sim_a.step(a)
        sim_b.step(a)
    assert not np.array_equal(sim_a.observe()["facilities"], sim_b.observe()["facilities"])
