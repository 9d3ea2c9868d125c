"""Hindsight oracles (wfbench.policies.oracle): registration, determinism, the shadow check, and that they pay."""

import numpy as np
import pytest
from wfbench.policies import kernels as K
from wfbench.policies import registry
from wfbench.policies.oracle import OracleDispatch, ShadowDivergedError
from wfbench.policies.oracle.best import BestInHindsight
from wfbench.policies.oracle.dispatch import dispatch_candidates
from wfbench.policies.oracle.positioning import hire_sites, release_targets

from wfbench import ScenarioConfig, Simulator, policies

SMALL = ScenarioConfig.preset("small")
SHORT = SMALL.replace(horizon=120)


def play(name, config, seeds):
    """The local evaluation loop of a trace-reading policy: attach, reset, act, step. Returns (means, policy)."""
    pol = policies.get(name)
    if getattr(pol, "reads_trace", False):
        pol.attach(config)
    sim = Simulator(config, seeds)
    obs = sim.reset()
    pol.reset(sim.seeds)
    while not sim.done:
        sim.step(pol.act(obs))
        obs = sim.observe()
    return sim.episode_means(), sim.counters(), pol


def test_oracles_are_registered_and_marked_as_reading_the_trace():
    assert {"oracle", "oracle-planner", "oracle-dispatch"} <= set(policies.names())
    for decision in ("dispatch", "workforce", "positioning"):
        assert "oracle" in policies.DECISIONS[decision]
    best = policies.get("oracle")
    assert isinstance(best, BestInHindsight) and best.reads_trace
    # its candidates: every deployable registered policy (none reads the trace) and the planner, except those added
    # after its numbers were published (a fixed set, so that a new policy does not move them)
    later = {"heuristic-tuned-train", "solver-tuned-train", "scalefree-general", "solver-sparse", "distill-general",
             "distill-switch-general"}
    assert set(best.candidates) == {*registry.deployable_names(), "oracle-planner"} - later
    assert not any(getattr(policies.get(n), "reads_trace", False) for n in registry.deployable_names())
    assert set(registry.learned_names()) - later <= set(best.candidates)
    assert "solver-tuned" in best.candidates
    assert not later & set(best.candidates)
    assert {n for n in registry.deployable_names() if "v1" not in registry.entry(n).candidate_of} == later
    full = policies.get("oracle-planner")
    assert full.reads_trace and not full.compiled
    assert not policies.get("heuristic").reads_trace
    planners = {id(p.planner) for p in full.parts.values()}
    assert len(planners) == 1  # one planner makes all three decisions
    assert full.parts["dispatch"].planner.decide == ("dispatch", "workforce", "positioning")
    od = policies.get("oracle-dispatch")
    planner = od.parts["dispatch"].planner
    assert planner.decide == ("dispatch",)
    # the built-in parts of the composite are modelled by their own kernels
    assert planner.base["workforce"][0] == K.W_THRESHOLD and planner.base["positioning"][0] == K.P_SPATIAL
    mixed = policies.Composite("oracle", "staffing", "oracle")
    assert mixed.parts["dispatch"].planner is mixed.parts["positioning"].planner
    assert mixed.parts["dispatch"].planner.base["workforce"][0] == K.W_STAFFING


@pytest.mark.parametrize("name", ["oracle", "oracle-v2", "oracle-rollout", "oracle-planner"])
def test_an_oracle_needs_the_scenario_before_reset(name):
    with pytest.raises(RuntimeError) as err:
        policies.get(name).reset([0])
    assert str(err.value) == ("a hindsight oracle needs the scenario: call attach(config) before reset(seeds) "
                              "(wfbench's runner does this for policies with reads_trace = True)")


def test_the_planner_is_deterministic_and_a_seed_plays_the_same_alone_or_in_a_batch():
    a, ca, _ = play("oracle-planner", SHORT, [1, 2])
    b, cb, _ = play("oracle-planner", SHORT, [1, 2])
    alone, c1, _ = play("oracle-planner", SHORT, [2])
    for k in a:
        assert np.array_equal(a[k], b[k]), k
        assert a[k][1] == alone[k][0], k
    assert all(np.array_equal(ca[k], cb[k]) for k in ca)
    assert ca["hires"].sum() + ca["releases"].sum() > 0  # the workforce oracle acts
    assert sum(ca[k].sum() for k in ("invalid_dispatch_not_requesting", "invalid_dispatch_unavailable",
                                     "invalid_dispatch_duplicate", "invalid_hire_no_slot")) == 0


def test_a_shadow_that_diverges_is_caught():
    pol = policies.get("oracle-dispatch")
    pol.attach(SHORT.replace(request_interval=10.0))  # not the world it will play
    sim = Simulator(SHORT, [0])
    obs = sim.reset()
    pol.reset(sim.seeds)
    with pytest.raises(ShadowDivergedError):
        for _ in range(SHORT.horizon):
            sim.step(pol.act(obs))
            obs = sim.observe()
    # an oracle for one decision must be told the joint action (a composite does it)
    lone = OracleDispatch()
    lone.attach(SHORT)
    sim = Simulator(SHORT, [0])
    obs = sim.reset()
    lone.reset([0])
    d = lone.act(obs)["dispatch"]
    sim.step({"dispatch": d, "workforce": np.zeros(1, dtype=np.int64), "positioning": np.zeros((1, 2, sim.M))})
    with pytest.raises(ShadowDivergedError, match="joint action"):
        lone.act(sim.observe())


def test_hindsight_dispatch_beats_heuristic_dispatch_on_small():
    seeds = list(range(6))
    oracle, _, pol = play("oracle-dispatch", SMALL, seeds)
    heuristic, _, _ = play("heuristic", SMALL, seeds)
    assert oracle["nsw"].mean() > heuristic["nsw"].mean()
    assert (oracle["nsw"] > heuristic["nsw"]).sum() >= 4  # on most seeds, not by one lucky episode
    assert pol.parts["dispatch"].planner.timing["dispatch_rolls"] > 0


def test_the_planner_beats_the_solver_composite_on_small():
    seeds = list(range(4))
    oracle, _, _ = play("oracle-planner", SMALL, seeds)
    solver, _, _ = play("solver", SMALL, seeds)
    assert (oracle["nsw"] > solver["nsw"]).all()


def test_dispatch_candidates_hold_back_and_send_the_person_who_will_fix_it():
    N = 3  # people; 3 facilities
    base = np.array([0, N, N])  # nearest-first: novice 0 to facility 0
    requesting = np.array([1, 0, 0])
    free = np.array([1, 1, 1])
    fac_xy = np.array([[0, 0], [5, 5], [9, 9]])
    per_xy = np.array([[1, 0], [3, 0], [6, 0]], dtype=np.float64)
    levels = np.array([0, 1, 2])
    fixes = {0: np.array([False, False, True])}  # only an expert fixes this visit
    cands = [tuple(c) for c in dispatch_candidates(base, requesting, free, fac_xy, per_xy, levels, fixes, 3)]
    assert cands[0] == (0, N, N)
    assert (N, N, N) in cands  # hold back
    assert (2, N, N) in cands  # the expert, who will fix it
    assert (1, N, N) in cands  # the runner-up
    assert len(cands) == len(set(cands))


def test_hire_at_the_known_demand_and_let_go_the_cheapest_loss():
    sites = np.array([[0, 0], [10, 10], [20, 0]])
    homes = np.array([[0, 0], [0, 1]])
    cells = np.array([[0, 0], [20, 0]])
    counts = np.array([1.0, 5.0])
    pm, greedy = hire_sites(sites, homes, cells, counts)
    assert pm == 2 and greedy == 2  # nobody lives near the busy cell (20, 0)
    # two people at one corner: home 0 is nearer every demand cell, so losing home 1 costs nothing;
    # the other levels have nobody to let go
    levels = np.array([1, 1])
    out = release_targets(homes, levels, np.array([True, True]), cells, counts)
    assert list(out) == [-1, 1, -1]
    assert list(release_targets(homes, levels, np.array([True, False]), cells, counts)) == [-1, 0, -1]
    homes3 = np.array([[0, 0], [0, 1], [20, 0]])
    out = release_targets(homes3, np.array([1, 1, 1]), np.array([True, True, True]), cells, counts)
    assert out[1] in (0, 1)  # never the one serving the busy cell


@pytest.mark.slow
def test_evaluate_hands_the_scenario_to_an_oracle_and_matches_the_local_loop_on_every_backend():
    import wfbench

    means, _, _ = play("oracle-dispatch", SHORT, [3, 4])
    for backend in ("serial", "process"):
        df = wfbench.evaluate("oracle-dispatch", SHORT, seeds=[3, 4], execution=wfbench.Execution(backend=backend))
        np.testing.assert_array_equal(df["nsw"].to_numpy(), means["nsw"], err_msg=backend)


class _Recorder:
    """A user's policy that records whether the runner handed it the scenario."""

    decisions = ("dispatch",)
    attached = []

    def __init__(self, declares):
        self.reads_trace = declares

    def attach(self, config):
        _Recorder.attached.append(config.name)

    def reset(self, seeds):
        self.n = len(seeds)

    def act(self, obs):
        m = obs["dispatch_mask"]
        return {"dispatch": np.full(m.shape[:2], m.shape[2] - 1, dtype=np.int64)}  # N: nobody


def test_only_a_policy_that_declares_reads_trace_is_handed_the_scenario():
    from wfbench.harness.runner import run_batch

    _Recorder.attached.clear()
    run_batch(policies.Composite(_Recorder(False), "threshold", "spatial"), SHORT, [0])
    assert _Recorder.attached == []
    run_batch(policies.Composite(_Recorder(True), "threshold", "spatial"), SHORT, [0])
    assert _Recorder.attached == [SHORT.name]


def _oracle_against_every_deployable(scenario, seeds, every_network=True):
    """Per seed: the oracle is at least every deployable built-in (each evaluated on its own), and it replays its
    choice exactly (the episode it plays is the one its chosen candidate played).

    Without ``every_network``, a network the oracle stopped early on every seed (provably below its choice) is not
    evaluated again: a network costs seconds per episode where a compiled built-in costs milliseconds.
    """
    import wfbench

    config = ScenarioConfig.preset(scenario)
    means, counters, pol = play("oracle", config, seeds)
    nsw = means["nsw"]
    chosen = np.array([pol.scores[b, pol.candidates.index(c)] for b, c in enumerate(pol.choice)])
    np.testing.assert_array_equal(nsw, chosen)  # bit for bit: the replay is the candidate's episode
    for name in pol.candidates:
        if name == "oracle-planner":
            continue
        stopped = np.isnan(pol.scores[:, pol.candidates.index(name)]).all()
        if not every_network and name in registry.learned_names() and stopped:
            continue
        theirs = wfbench.evaluate(name, config, seeds=seeds)["nsw"].to_numpy()
        assert np.all(nsw >= theirs), (scenario, name, nsw, theirs)
        k = pol.candidates.index(name)
        played = ~np.isnan(pol.scores[:, k])  # NaN: stopped early, provably below the best
        np.testing.assert_array_equal(pol.scores[played, k], theirs[played], err_msg=name)
    return pol


@pytest.mark.slow
def test_the_oracle_is_at_least_every_deployable_builtin_on_every_seed_of_small():
    pol = _oracle_against_every_deployable("small", [0, 1, 2])
    assert pol.timing.keys() == set(pol.candidates)


@pytest.mark.slow
def test_the_oracle_is_at_least_every_deployable_builtin_on_a_paper_64_sized_world():
    # table2-g128-f50-s25: the shipped networks beat the planner here on most seeds (issue #27)
    pol = _oracle_against_every_deployable("table2-g128-f50-s25", [0, 1], every_network=False)
    assert set(pol.choice) - {"oracle-planner"}, "a network or a built-in is chosen on some seed"


def test_the_oracle_replays_a_compiled_candidate_on_the_seeds_that_chose_it():
    """Candidates replayed live (a compiled composite on a sub-batch) and recorded ones (a network) side by side."""
    config = SMALL
    best = BestInHindsight(["random-positioning", "ppo-joint"], policies.get, name="two")
    best.attach(config)
    seeds = [0, 1, 2, 3, 4, 5]
    best.reset(seeds)
    want = np.nanmax(best.scores, axis=1)
    sim = Simulator(config, seeds)
    obs = sim.reset()
    while not sim.done:
        sim.step(best.act(obs))
        obs = sim.observe()
    np.testing.assert_array_equal(sim.episode_means()["nsw"], want)
    assert len({c for c in best.choice}) >= 2, best.choice  # both kinds of replay ran in one batch


def test_the_oracle_refuses_without_torch_rather_than_drop_the_networks(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a))
    with pytest.raises(ValueError, match=r"needs torch; install the rl extra: pip install 'wfbench\[rl\]'"):
        policies.get("oracle")
    assert policies.get("oracle-planner").reads_trace  # the planner alone needs no torch


@pytest.mark.slow
def test_the_oracle_plays_a_seed_the_same_alone_or_in_a_batch():
    import wfbench

    both = wfbench.evaluate("oracle", SHORT, seeds=[1, 2])
    alone = wfbench.evaluate("oracle", SHORT, seeds=[2])
    assert both["nsw"].iloc[1] == alone["nsw"].iloc[0]
    assert both["hires"].iloc[1] == alone["hires"].iloc[0]
