"""The proven upper bound on the score (issue #12, docs/hindsight.md "The upper bound").

No policy may exceed the bound on any seed: the built-in ones, the oracles, and
adversarial policies that push one utility to its extreme. The ``oracle`` scores at
least every deployable built-in on every seed (tests/policies/test_oracles.py), so the bound
holding for it on a seed holds for all of them there. Each step of
the argument is checked on its own against the simulator's per-step series too, so a
wrong step fails here even when the whole bound still happens to hold.
"""

import numpy as np
import pytest

import wfbench
from wfbench import policies
from wfbench.core.bound import bound_parts, occupancies, score_upper_bound
from wfbench.core.config import ScenarioConfig
from wfbench.core.state import METRICS
from wfbench.core.trace import trace

BUILTIN = ["random", "heuristic", "heuristic-stochastic", "solver", "random-dispatch", "fixed-workforce"]
K_NSW, K_UWC, K_UPUR, K_AFD = (METRICS.index(k) for k in ("nsw", "u_cost", "u_utilization", "downtime"))


class _Workforce:
    """Let go (or hire) at every step it can: the cheapest or the dearest workforce the rules allow."""

    decisions = ("workforce",)

    def __init__(self, codes, name):
        self.codes, self.name = codes, name

    def reset(self, seeds):
        self.n = len(seeds)

    def act(self, obs):
        out = np.zeros(self.n, dtype=np.int64)
        for b in range(self.n):
            for code in self.codes:
                if obs["workforce_mask"][b, code]:
                    out[b] = code
                    break
        return {"workforce": out}


def _adversaries():
    fire = _Workforce([6, 5, 4], "fire-everyone")  # let go the dearest level first: u_WC as high as it goes
    hire = _Workforce([1], "hire-everyone")  # novices in every free slot: all the hands there can be
    return [policies.Composite(dispatch="nearest", workforce=fire, positioning="spatial"),
            policies.Composite(dispatch="nearest", workforce=hire, positioning="spatial")]


def _oracles():
    """The planners, on many seeds (the best-in-hindsight ``oracle`` costs more: its own test, on fewer seeds)."""
    return [n for n in ("oracle-planner", "oracle-dispatch") if n in policies.names()]


# the scenarios issue #27 added to the suite, paper-64-sized (city: see test_bound__holds_on_the_city_world)
NEW_SCENARIOS = ["surge-64", "clustered-64", "slow-64", "churn-64", "novice-64", "real-benelux", "real-nyc"]


def _scores(policy, scenario, seeds):
    """Episode scores per seed (the runner hands a trace-reading oracle its scenario)."""
    return wfbench.evaluate(policy, scenario, seeds=seeds)["nsw"].to_numpy()


def _check_never_exceeded(scenario, seeds, oracle_seeds):
    """Every built-in and adversarial policy on ``seeds``, the oracles (slower) on ``oracle_seeds``."""
    bound = score_upper_bound(wfbench.scenario(scenario), seeds)
    runs = [(p, seeds) for p in BUILTIN + _adversaries()] + [(p, oracle_seeds) for p in _oracles()]
    for policy, run_seeds in runs:
        score = _scores(policy, scenario, run_seeds)
        bound_here = bound[: len(run_seeds)]  # the oracles' seeds are a prefix of seeds
        over = np.flatnonzero(score > bound_here)
        assert over.size == 0, (f"{policy} scores above the bound on {scenario}, seeds "
                                f"{[run_seeds[i] for i in over[:5]]}: {score[over[:5]]} > {bound_here[over[:5]]}")
    return bound


@pytest.mark.slow
def test_bound__no_policy_exceeds_it_on_200_small_seeds():
    seeds = list(range(200))
    bound = _check_never_exceeded("small", seeds, seeds[:100])
    assert bound.shape == (200,)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["paper-64", "nonstationary", "table2-g32-f25-s10"])
def test_bound__no_policy_exceeds_it_on_the_larger_scenarios(scenario):
    _check_never_exceeded(scenario, list(range(20)), list(range(4)))


@pytest.mark.parametrize("scenario, n", [("small", 40), ("paper-64", 8), ("nonstationary", 8)])
def test_bound__each_step_of_the_argument_holds_on_the_series(scenario, n):
    """NSW is 0 before t*, u_WC and u_PUR stay under their per-step bounds, the downtime after t* above its bound."""
    config = ScenarioConfig.preset(scenario)
    parts = [bound_parts(config, s) for s in range(n)]
    for policy in ["heuristic", "random", "solver", *_adversaries()]:
        _, series = wfbench.evaluate(policy, scenario, seeds=n, return_series=True)
        for s, p in enumerate(parts):
            assert np.all(series[s, : p.first_failure, K_NSW] == 0.0), (policy, s)
            t0 = p.first_failure
            assert np.all(series[s, :, K_UWC] <= p.wc_utility + 1e-6), (policy, s)  # the series is float32
            assert np.all(series[s, :, K_UPUR] <= p.pur_utility + 1e-6), (policy, s)
            afd = series[s, t0:, K_AFD].sum()
            assert afd >= p.downtime_sum * (1 - 1e-5), (policy, s, afd, p.downtime_sum)


def test_bound__is_below_the_trivial_bound_by_a_margin():
    for scenario in ["small", "paper-64", "nonstationary"]:
        bound = score_upper_bound(wfbench.scenario(scenario), 50)
        assert np.all(bound < 0.98), (scenario, bound.max())
        assert np.all(bound > 0.5), (scenario, bound.min())  # not vacuous the other way: the heuristic scores ~0.6-0.7


def test_bound__is_a_pure_function_of_the_seed():
    all_five = score_upper_bound(wfbench.scenario("small"), 5)
    assert score_upper_bound(wfbench.scenario("small"), [3])[0] == all_five[3]
    assert np.array_equal(score_upper_bound(ScenarioConfig.preset("small"), [0, 1, 2, 3, 4]), all_five)


def test_bound__is_zero_when_nothing_can_fail():
    """With no failure in the episode nobody ever works, every NSW_t is 0, and so is the bound."""
    config = ScenarioConfig.preset("small").replace(request_interval=1e12)
    assert np.all(score_upper_bound(config, 5) == 0.0)
    assert np.all(wfbench.evaluate("heuristic", config, seeds=5)["nsw"] == 0.0)


def test_bound__occupancies_follow_the_slots_of_the_simulator():
    """Arrivals into the lowest free slot, exits first: the same active set as the simulator's, step by step."""
    config = ScenarioConfig.preset("small").replace(churn_interval=5.0, max_facilities=10)
    sim = wfbench.Simulator(config, seeds=[7])
    sim.reset()
    occ = occupancies(config, trace(config, 7))
    noop = {"dispatch": np.full((1, config.max_facilities), config.max_personnel), "workforce": np.zeros(1, np.int64),
            "positioning": np.zeros((1, 2, config.max_facilities))}
    for t in range(config.horizon):
        expect = np.zeros(config.max_facilities, dtype=bool)
        for f, a, e in occ:
            if a <= t < e:
                assert not expect[f]
                expect[f] = True
        assert np.array_equal(sim.state.fac_active[0], expect), t
        sim.step(noop)


def _edge_config():
    """``small`` at the edges of the rules the bound uses: a failure rate that swings 10x within 40 steps, fast churn
    (slots reused often), one-step service, let-gos that take effect at once, nobody kept on."""
    from wfbench.core.schedule import RateSchedule

    return ScenarioConfig.preset("small").replace(
        name="bound-edges", request_schedule=RateSchedule(kind="seasonal", amplitude=0.9, period=40.0),
        churn_interval=8.0, service_time=1, fire_delay=0, min_personnel=0, request_interval=15.0)


def test_bound__holds_at_the_edges_of_the_rules():
    config = _edge_config()
    seeds = list(range(60))
    bound = score_upper_bound(config, seeds)
    parts = [bound_parts(config, s) for s in seeds]
    assert np.all(bound < 1.0)
    for policy in BUILTIN + _adversaries():
        df, series = wfbench.evaluate(policy, config, seeds=seeds, return_series=True)
        assert np.all(df["nsw"].to_numpy() <= bound), policy
        for s, p in enumerate(parts):
            assert np.all(series[s, : p.first_failure, K_NSW] == 0.0), (policy, s)
            assert np.all(series[s, :, K_UWC] <= p.wc_utility + 1e-6), (policy, s)
            assert np.all(series[s, :, K_UPUR] <= p.pur_utility + 1e-6), (policy, s)
            assert series[s, p.first_failure:, K_AFD].sum() >= p.downtime_sum * (1 - 1e-5), (policy, s)


ORACLE_CHECKED = ("surge-64", "real-nyc")
"""Where the test plays the oracle itself (about 11 s a seed); `wfbench reproduce suite` checks it on every scenario."""


@pytest.mark.slow
@pytest.mark.parametrize("scenario", NEW_SCENARIOS)
def test_bound__holds_against_the_best_policies_on_the_new_scenarios(scenario):
    """The heuristic and the adversaries stay under the bound on three seeds and each step of the argument holds on
    their series; on a shift and a real-data scenario the best in hindsight (every deployable built-in, the shipped
    networks and the planner) stays under it on seed 0 too. The oracle is at least every deployable built-in on every
    seed (tests/policies/test_oracles.py), so its seed covers them all; the suite's reproduction checks every
    policy against the bound on every scenario and seed it runs (docs/suite.md)."""
    seeds = list(range(3))
    bound = score_upper_bound(wfbench.scenario(scenario), seeds)
    assert np.all((bound > 0.5) & (bound < 0.98)), (scenario, bound)
    if scenario in ORACLE_CHECKED:
        oracle = _scores("oracle", scenario, [0])
        assert oracle[0] <= bound[0], (scenario, oracle, bound[0])
        assert oracle[0] >= _scores("heuristic", scenario, [0])[0]  # it is the best one: the check has teeth
    config = ScenarioConfig.preset(scenario)
    parts = [bound_parts(config, s) for s in seeds]
    for policy in ["heuristic", *_adversaries()]:
        df, series = wfbench.evaluate(policy, scenario, seeds=seeds, return_series=True)
        assert np.all(df["nsw"].to_numpy() <= bound), (scenario, policy)
        for s, p in enumerate(parts):
            assert np.all(series[s, : p.first_failure, K_NSW] == 0.0), (scenario, policy, s)
            assert np.all(series[s, :, K_UWC] <= p.wc_utility + 1e-6), (scenario, policy, s)
            assert np.all(series[s, :, K_UPUR] <= p.pur_utility + 1e-6), (scenario, policy, s)
            assert series[s, p.first_failure:, K_AFD].sum() >= p.downtime_sum * (1 - 1e-5), (scenario, policy, s)


@pytest.mark.slow
def test_bound__holds_on_the_city_world():
    """city (576x576, 500 facilities and 500 people at start): one seed, the fast built-ins and the adversaries.

    The oracle is not run here: on city it plays every candidate, minutes for one seed (docs/hindsight.md, "What it
    scores and costs"); its score on seed 0 is below the bound there too.
    """
    config = ScenarioConfig.preset("city")
    bound = score_upper_bound(config, [0])
    assert 0.5 < bound[0] < 0.98, bound
    p = bound_parts(config, 0)
    for policy in ["heuristic", *_adversaries()]:
        df, series = wfbench.evaluate(policy, config, seeds=[0], return_series=True)
        assert df["nsw"].iloc[0] <= bound[0], policy
        assert np.all(series[0, : p.first_failure, K_NSW] == 0.0), policy
        assert np.all(series[0, :, K_UWC] <= p.wc_utility + 1e-6), policy
        assert np.all(series[0, :, K_UPUR] <= p.pur_utility + 1e-6), policy
        assert series[0, p.first_failure:, K_AFD].sum() >= p.downtime_sum * (1 - 1e-5), policy
