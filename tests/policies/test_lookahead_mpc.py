"""mpc-rates and mpc-ma (wfbench.policies.lookahead.mpc, issue #43): knobs, registry, an episode against its base.

Public seeds only (1000-1049).
"""

import numpy as np
import pytest
from wfbench.policies.lookahead import MPC
from wfbench.policies.registry import lookahead_names, names, parse_spec, parts

from wfbench import ScenarioConfig, policies
from wfbench.harness.runner import run_batch
from wfbench.scenarios.resolve import resolve_scenario


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
        assert name in lookahead_names() and name not in names() and parse_spec(name).kind == "lookahead"
        pol = policies.get(name)
        assert isinstance(pol, MPC) and pol.forecast == kind and pol.name == name
        assert kind in parts(name)[1]
    assert policies.get("mpc-ma").settings() == {"H": 100, "R": 20, "window": 100}


def test_the_calibrated_presets_are_the_same_mpc_with_calibrate_on():
    for name, kind in (("mpc-rates-calibrated", "rates"), ("mpc-ma-calibrated", "ma")):
        assert name in lookahead_names() and name not in names() and parse_spec(name).kind == "lookahead"
        pol, plain = policies.get(name), policies.get(f"mpc-{kind}")
        assert isinstance(pol, MPC) and pol.forecast == kind and pol.name == name
        assert pol.calibrate is True and plain.calibrate is False
        assert all(pol.settings()[k] == plain.settings()[k] for k in ("H", "R"))  # the same budget
        assert pol.settings()["calibrate"] is True and "calibrated" in parts(name)[1]


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
    config = resolve_scenario("paper-64")
    seeds = [1000, 1001, 1002]
    base = run_batch(policies.get("solver-tuned-train"), config, seeds).means["nsw"]
    for name in ("mpc-rates", "mpc-ma"):
        d = run_batch(policies.get(name), config, seeds).means["nsw"] - base
        assert -0.08 < d.mean() < 0.0, (name, d)


def test_its_tunable_parameters_round_trip_and_bad_ones_get_one_line():
    pol = policies.get("mpc-ma")
    assert set(pol.tunable) == {"H", "R", "window", "shortfall_cost", "action_cost", "capacity_scale"}
    assert "window" not in policies.get("mpc-rates").tunable, "the rates forecast has no moving average"
    assert pol.params() == {"H": 100, "R": 20, "window": 100, "shortfall_cost": 1000.0, "action_cost": 50.0,
                            "capacity_scale": 1.0}
    tuned = pol.with_params({"H": 60, "capacity_scale": 1.25}, name="mpc-ma-mine")
    assert tuned.name == "mpc-ma-mine" and tuned.forecast == "ma" and tuned.base is pol.base
    assert tuned.params() == {**pol.params(), "H": 60, "capacity_scale": 1.25}
    assert pol.params()["H"] == 100, "the original is unchanged"
    with pytest.raises(ValueError, match="has no tunable parameter 'window'; allowed: H, R, shortfall_cost") as err:
        policies.get("mpc-rates").with_params({"window": 50})
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match=r"capacity_scale = 3 is out of range; allowed: float in \[0.5, 2\]"):
        pol.with_params({"capacity_scale": 3})


def test_a_tuned_file_of_it_loads_by_path(tmp_path):
    from wfbench.policies.tuned import TunedPolicy, write

    path = write(TunedPolicy(name="mpc-rates-mine", base="mpc-rates", params={"R": 40, "action_cost": 200.0},
                             scenario="suite-v1:train", seeds=[1000], trials=1, best_score=0.5),
                 tmp_path / "mine.json")
    pol = policies.get(str(path))
    assert isinstance(pol, MPC) and pol.name == "mpc-rates-mine" and pol.forecast == "rates"
    assert pol.R == 40 and pol.action_cost == 200.0 and pol.H == 100


def test_its_solves_are_limited_in_work_not_time(monkeypatch):
    """A wall-clock limit makes the plan depend on the machine's load; the node limit does not."""
    import wfbench.policies.lookahead.mpc as mpc

    seen = []
    real = mpc.plan_staffing

    def spy(inst, time_limit=None, block=1, node_limit=None):
        seen.append((time_limit, node_limit))
        return real(inst, time_limit=time_limit, block=block, node_limit=node_limit)

    monkeypatch.setattr(mpc, "plan_staffing", spy)
    pol = policies.get("mpc-ma")
    run_batch(pol, ScenarioConfig.preset("small").replace(horizon=30), [1000])
    assert seen and set(seen) == {(None, mpc.NODE_LIMIT)}
    with pytest.raises(ValueError, match="mpc knob node_limit = 0 is not allowed"):
        MPC(pol.base, node_limit=0)


def test_the_tuned_presets_load_their_shipped_files():
    import json

    for kind in ("rates", "ma"):
        name = f"mpc-{kind}-tuned-train"
        spec = parse_spec(name)
        assert name in lookahead_names() and name not in names() and spec.kind == "lookahead"
        shipped = json.loads(spec.file.read_text())
        assert spec.file.name == f"mpc-{kind}-suite-v1-train.json" and shipped["base"] == f"mpc-{kind}"
        assert shipped["scenario"] == "suite-v1:train" and all(1000 <= s <= 1049 for s in shipped["seeds"])
        pol = policies.get(name)
        assert isinstance(pol, MPC) and pol.name == name and pol.forecast == kind
        assert pol.params() == shipped["params"]
        assert all(p.endswith("(tuned)") for p in parts(name))


def test_calibrate_is_refused_unless_a_bool_and_survives_with_params():
    pol = policies.get("mpc-ma")
    assert pol.calibrate is False and "calibrate" not in pol.settings(), "the default path is today's model"
    with pytest.raises(ValueError, match="mpc calibrate = 'yes' is not allowed; allowed: True or False"):
        MPC(pol.base, calibrate="yes")
    on = MPC(pol.base, forecast="ma", calibrate=True)
    assert on.settings() == {"H": 100, "R": 20, "window": 100, "calibrate": True}
    assert on.with_params({"H": 60}).calibrate is True


def test_the_default_never_reads_the_calibration_state(monkeypatch):
    """calibrate=False plays today's model: garbage in the calibration's counters changes no action."""
    config = ScenarioConfig.preset("small").replace(horizon=80)
    plain = run_batch(policies.get("mpc-rates"), config, [1000, 1001])
    real = MPC._observe

    def poisoned(self, obs, t):
        real(self, obs, t)
        self.seen_repairs[:] = 1e9
        self.busy_steps[:] = 7.0
        self.up_ring[:] = 0.01

    monkeypatch.setattr(MPC, "_observe", poisoned)
    again = run_batch(policies.get("mpc-rates"), config, [1000, 1001])
    assert np.array_equal(plain.means["nsw"], again.means["nsw"])
    assert all(np.array_equal(plain.counters[k], again.counters[k]) for k in plain.counters)


def test_calibrated_ma_waits_for_a_full_window_and_measures_its_rate():
    """At step 0 the moving average has seen no request: today's model then lets go of nearly everyone."""
    config = ScenarioConfig.preset("small").replace(horizon=60)
    base = policies.get("solver-tuned-train")
    pol = MPC(base, forecast="ma", H=40, R=10, window=20, calibrate=True)
    r = run_batch(pol, config, [1000, 1001])
    assert pol.timing["solves"] == 2 * 5, "solves at steps 19, 29, 39, 49, 59 only"
    assert (pol.plan_t0 == 59).all() and all(res.has_solution for res in pol.last)
    assert (pol.busy_steps.sum(-1) > 0).all() and np.isfinite(r.means["nsw"]).all()
    plain = MPC(base, forecast="ma", H=40, R=10, window=20)  # the same state, today's model
    plain.__dict__.update({k: v.copy() if isinstance(v, np.ndarray) else v for k, v in pol.__dict__.items()
                           if k != "calibrate"})
    obs = _last_obs(config)
    on, off = pol._instance(0, 59, obs), plain._instance(0, 59, obs)
    factor = on.capacity / off.capacity
    assert np.allclose(factor, factor[0]) and factor[0] != 1.0, "one measured factor on every level's capacity"
    assert np.array_equal(on.demand, off.demand), "the moving average's forecast is the same"


def _last_obs(config):
    from wfbench import Simulator

    sim = Simulator(config, [1000, 1001])
    sim.reset()
    return sim.observe()


def test_the_backlog_presets_are_the_calibrated_mpc_with_its_queue_on():
    for name, kind in (("mpc-rates-backlog", "rates"), ("mpc-ma-backlog", "ma")):
        assert name in lookahead_names() and name not in names() and parse_spec(name).kind == "lookahead"
        pol, calibrated = policies.get(name), policies.get(f"mpc-{kind}-calibrated")
        assert isinstance(pol, MPC) and pol.forecast == kind and pol.name == name
        assert pol.backlog is True and pol.calibrate is True and calibrated.backlog is False
        assert pol.settings() == {**calibrated.settings(), "backlog": True}  # the same budget
        assert "backlog" in parts(name)[1]
    for name in ("mpc-rates", "mpc-ma", "mpc-rates-calibrated", "mpc-ma-calibrated"):
        assert policies.get(name).backlog is False, f"{name}'s committed numbers are the model without a queue"


def test_backlog_is_refused_unless_a_bool_and_its_price_is_tunable_in_its_place():
    pol = policies.get("mpc-ma")
    for bad in ("yes", 1, None):
        with pytest.raises(ValueError) as err:
            MPC(pol.base, backlog=bad)
        assert str(err.value) == f"mpc backlog = {bad!r} is not allowed; allowed: True or False"
    with pytest.raises(ValueError, match=r"backlog_weight = 0 is out of range; allowed: float in \[0.1, 100\]") as err:
        MPC(pol.base, backlog=True, backlog_weight=0)
    assert "\n" not in str(err.value)
    on = policies.get("mpc-ma-backlog")
    assert set(on.tunable) == {*pol.tunable, "backlog_weight"}, "coverage is still priced: the queue adds to it"
    assert "backlog_weight" not in pol.tunable, "today's presets tune what they tuned"
    again = on.with_params({"backlog_weight": 3.0, "H": 60})
    assert again.backlog and again.calibrate and again.backlog_weight == 3.0 and again.H == 60


def test_the_queue_is_seeded_from_the_requests_waiting_and_priced_at_the_exchange_rate():
    config = ScenarioConfig.preset("small").replace(horizon=40)
    pol = MPC(policies.get("solver-tuned-train"), forecast="rates", H=30, R=10, backlog=True, backlog_weight=2.0)
    r = run_batch(pol, config, [1000, 1001])
    assert pol.timing["solves"] == 2 * 4 and all(res.status == "optimal" for res in pol.last)
    assert all("backlog" in res.detail for res in pol.last) and np.isfinite(r.means["nsw"]).all()
    from wfbench import Simulator

    sim = Simulator(config, [1000, 1001])
    sim.reset()
    for _ in range(25):  # nobody dispatched: requests wait
        sim.step({"dispatch": np.full((2, sim.M), sim.N), "workforce": np.zeros(2, dtype=np.int64),
                  "positioning": np.zeros((2, 2, sim.M))})
    obs = sim.observe()
    waiting = np.asarray(obs["requesting"]).sum(-1)
    assert waiting.max() > 0, "the instance below must see a backlog"
    for b in range(2):
        inst = pol._instance(b, 25, obs)
        active = np.asarray(obs["facility_mask"])[b].sum()
        assert inst.backlog0 == waiting[b]
        assert inst.backlog_cost == pytest.approx(2.0 * config.max_personnel * max(config.level_salaries) / active)
    plain = MPC(pol.base, forecast="rates", H=30, R=10)
    plain.__dict__.update({k: v for k, v in pol.__dict__.items() if k not in ("backlog", "backlog_weight")})
    assert plain._instance(0, 25, obs).backlog0 is None, "without the knob, the MILP has no queue"


@pytest.mark.slow  # two processes, one large-v1 episode each: about 30 s
def test_the_calibrated_plan_does_not_depend_on_the_cpu_s_blas_kernel():
    # large-v1 test seed 1: under OpenBLAS's AVX-512 dot the calibration's capacity moved one ulp and the MILP took
    # the other of two plans of equal cost (0.7886 against the suite's 0.7899, made on a CPU without AVX-512)
    import csv
    import os
    import subprocess
    import sys
    from pathlib import Path

    from wfbench.reproduce.provenance import machine

    kernels = ["Haswell", "SkylakeX" if "avx512f" in machine()["cpu_flags"] else "Nehalem"]
    code = ("import wfbench; df = wfbench.evaluate('mpc-ma-calibrated', 'large', seeds=[1]); "
            "print(repr(float(df['nsw'].iloc[0])))")
    got = {}
    for kernel in kernels:
        env = dict(os.environ, OPENBLAS_CORETYPE=kernel, NUMBA_NUM_THREADS="1")
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        got[kernel] = float(out.stdout.strip().splitlines()[-1])
    piece = Path(__file__).resolve().parents[2] / "docs/results/suite-v1-50/cache/mpc-ma-calibrated/large-v1.csv"
    with open(piece) as f:
        committed = next(float(r["nsw"]) for r in csv.DictReader(f) if int(r["seed"]) == 1)
    assert got[kernels[0]] == got[kernels[1]], got
    assert got[kernels[0]] == pytest.approx(committed, rel=0, abs=1e-15), (got, committed)
