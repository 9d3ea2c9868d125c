"""mpc-rates and mpc-ma (wfbench.policies.lookahead.mpc, issue #43): knobs, registry, an episode against its base.

Public seeds only (1000-1049).
"""

import numpy as np
import pytest
from wfbench.policies.lookahead import MPC
from wfbench.policies.registry import LOOKAHEAD, names, parse_spec, parts

from wfbench import ScenarioConfig, policies
from wfbench.harness.runner import run_batch


@pytest.mark.parametrize("knobs, named", [
    ({"H": 0}, "H = 0"), ({"R": -2}, "R = -2"), ({"window": "ten"}, "window = 'ten'"), ({"H": 2.5}, "H = 2.5"),
    ({"R": float("inf")}, "R = inf"), ({"window": None}, "window = None"),
])
def test_bad_knobs_get_one_line_naming_the_knob(knobs, named):
    with pytest.raises(ValueError, match="allowed: an integer >= 1") as err:
        MPC(policies.get("solver-tuned-train"), **knobs)
    assert named in str(err.value) and str(err.value).startswith("mpc knob") and "\n" not in str(err.value)


def test_bad_forecast_and_base_and_a_missing_world_are_refused_in_one_line():
    with pytest.raises(ValueError, match="forecast 'oracle' is not allowed; allowed: rates, ma"):
        MPC(policies.get("solver-tuned-train"), forecast="oracle")
    with pytest.raises(ValueError, match="not a composite of built-in kernels"):
        MPC(policies.get("oracle-planner"))
    from wfbench import Simulator

    sim = Simulator(ScenarioConfig.preset("small").replace(horizon=3), [1000])
    pol = policies.get("mpc-rates")
    pol.reset([1000])
    with pytest.raises(ValueError, match="needs the world's public config.*allowed without it: mpc-ma"):
        pol.act(sim.reset())


def test_both_kinds_are_registered_apart_and_not_in_names():
    for name, kind in (("mpc-rates", "rates"), ("mpc-ma", "ma")):
        assert name in LOOKAHEAD and name not in names() and parse_spec(name).kind == "lookahead"
        pol = policies.get(name)
        assert isinstance(pol, MPC) and pol.forecast == kind and pol.name == name
        assert kind in parts(name)[1]
    assert policies.get("mpc-ma").settings() == {"H": 100, "R": 20, "window": 100}


def test_a_short_episode_follows_its_plan():
    config = ScenarioConfig.preset("small").replace(horizon=60)
    for name in ("mpc-rates", "mpc-ma"):
        pol = policies.get(name)
        pol.H, pol.R = 40, 10
        r = run_batch(pol, config, [1000, 1001])  # the runner hands mpc-rates the world (set_world)
        assert pol.timing["solves"] == 2 * 6 and all(res.has_solution for res in pol.last)
        assert r.counters["invalid_release_none"].sum() == 0 and r.counters["invalid_hire_no_slot"].sum() == 0
        assert np.isfinite(r.means["nsw"]).all()


@pytest.mark.slow  # three full paper-64 episodes of each kind and the base: about a minute on 2 cores
def test_on_paper_64_mpc_is_below_solver_tuned_train_as_documented():
    """Measured, not wished: docs/policies.md ("mpc") gives these numbers. mpc-rates is worse than its
    base beyond noise on these seeds, mpc-ma within about two standard errors below it."""
    config = ScenarioConfig.resolve("paper-64")
    seeds = [1000, 1001, 1002]
    base = run_batch(policies.get("solver-tuned-train"), config, seeds).means["nsw"]
    for name in ("mpc-rates", "mpc-ma"):
        d = run_batch(policies.get(name), config, seeds).means["nsw"] - base
        assert -0.08 < d.mean() < 0.0, (name, d)
