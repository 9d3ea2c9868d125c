"""Bad input: a clear error that names what is wrong and what is allowed, and nothing lost."""

import subprocess
import sys

import numpy as np
import pytest

from wfbench import ActionError, RateSchedule, ScenarioConfig, Simulator
from wfbench.cli import main


@pytest.mark.parametrize(("field", "value", "allowed"), [
    ("speed", -1.0, "> 0"),
    ("grid_width", 0, "integer in"),
    ("initial_personnel", 99, r"\[0, 50\]"),
    ("level_probs", (0.5, 0.5, 0.5), "sum to 1"),
    ("placement", "middle", "argmax"),
    ("horizon", 2.5, "integer"),
    ("request_interval", float("nan"), "finite"),
])
def test_config_error_names_field_value_and_range(field, value, allowed):
    with pytest.raises(ValueError, match=rf"ScenarioConfig\.{field} = .*allowed: .*{allowed}"):
        ScenarioConfig.preset("paper-64").replace(**{field: value})


def test_unknown_config_field_lists_the_fields():
    with pytest.raises(ValueError, match="unknown ScenarioConfig field.*allowed"):
        ScenarioConfig.preset("paper-64").replace(sped=2)


def _name_at_the_core():
    """What is inward of the edges, each handed a scenario's name instead of its config (docs/design.md)."""
    from wfbench import policies
    from wfbench.core.belief import Belief, PublicModel
    from wfbench.core.bound import score_upper_bound
    from wfbench.envs.parallel import WorkforceCore

    return [("Simulator", lambda: Simulator("small", [0])),
            ("Belief", lambda: Belief("small")),
            ("PublicModel.from_config", lambda: PublicModel.from_config("small")),
            ("score_upper_bound", lambda: score_upper_bound("small", 2)),
            ("WorkforceCore", lambda: WorkforceCore("small", None)),
            ("BestInHindsight.attach", lambda: policies.get("oracle").attach("small"))]


@pytest.mark.parametrize("index", range(6))
def test_a_name_given_to_the_core_is_one_typeerror_naming_the_resolver(index):
    owner, call = _name_at_the_core()[index]
    with pytest.raises(TypeError) as raised:
        call()
    message = str(raised.value)
    assert "\n" not in message
    assert message.startswith(f"{owner} takes a ScenarioConfig, got str 'small'")
    assert message.endswith("e.g. wfbench.scenario('small')")


def test_the_public_resolver_gives_the_config_the_core_takes():
    import wfbench

    assert wfbench.scenario("small") is ScenarioConfig.preset("small")
    from wfbench.scenarios.suites import SUITES

    assert wfbench.scenario("paper-64-v1") is SUITES["suite-v1"].scenario("paper-64-v1").config
    config = ScenarioConfig.preset("small")
    assert wfbench.scenario(config) is config
    assert Simulator(wfbench.scenario("small"), [0]).config is config


def test_bad_schedule():
    with pytest.raises(ValueError, match="amplitude must be in"):
        RateSchedule(kind="seasonal", amplitude=1.5)


@pytest.fixture
def sim(tiny):
    s = Simulator(tiny, [0])
    s.reset()
    return s


def ok_actions(M=5, N=3):
    return {"dispatch": np.full((1, M), N), "workforce": np.zeros(1, int), "positioning": np.zeros((1, 2, M))}


@pytest.mark.parametrize(("agent", "value", "message"), [
    ("dispatch", np.full((1, 4), 3), r"dispatch action has shape \(1, 4\)"),
    ("dispatch", np.array([[3, 3, 9, 3, 3]]), r"dispatch action: 9 at index \(0, 2\) is out of range"),
    ("dispatch", np.array([[3, 3, 3, np.nan, 3]]), r"dispatch action: nan at index \(0, 3\)"),
    ("workforce", np.array([7]), r"workforce action: 7 at index \(0,\) is out of range; allowed: integers 0..6"),
    ("positioning", np.full((1, 2, 5), np.nan), r"positioning action: nan at index \(0, 0, 0\)"),
    ("positioning", np.full((1, 2, 5), 1.5), r"positioning action: 1.5 .* allowed: numbers in \[0, 1\]"),
])
def test_malformed_action_names_agent_and_index(sim, agent, value, message):
    before = sim.state.t.copy()
    actions = ok_actions()
    actions[agent] = value
    with pytest.raises(ActionError, match=message):
        sim.step(actions)
    assert np.array_equal(sim.state.t, before), "a rejected action must not advance the simulation"


def test_impossible_actions_are_ignored_and_counted(sim):
    S = sim.state
    # facility 0 is not down at t=0 in this trace: force a known situation
    S.fac_down[0, :] = False
    actions = ok_actions()
    actions["dispatch"] = np.array([[0, 3, 3, 3, 3]])  # facility 0 has no open request
    sim.step(actions)
    assert sim.counters(0)["invalid_dispatch_not_requesting"] == 1
    S.fac_down[0, 1] = True
    S.fac_down[0, 2] = True
    S.fac_assigned[0, 1:3] = -1
    actions["dispatch"] = np.array([[3, 0, 0, 3, 3]])  # one person to two facilities
    sim.step(actions)
    c = sim.counters(0)
    assert c["invalid_dispatch_duplicate"] == 1
    assert S.fac_assigned[0, 1] == 0 and S.fac_assigned[0, 2] == -1
    actions["dispatch"] = np.array([[3, 3, 0, 3, 3]])  # person 0 is busy now
    sim.step(actions)
    assert sim.counters(0)["invalid_dispatch_unavailable"] == 1


def test_hire_without_free_slot_and_release_at_minimum_are_counted(tiny):
    sim = Simulator(tiny.replace(min_personnel=3), [0])
    sim.reset()
    a = ok_actions()
    a["workforce"] = np.array([2])  # all 3 slots are taken
    sim.step(a)
    a["workforce"] = np.array([5])  # headcount is at min_personnel
    sim.step(a)
    c = sim.counters(0)
    assert c["invalid_hire_no_slot"] == 1 and c["invalid_release_none"] == 1


def test_cli_unknown_policy_is_one_line_exit_2(capsys):
    assert main(["evaluate", "--policy", "nope", "--seeds", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown policy 'nope'" in err[0] and "heuristic" in err[0]


def test_cli_unknown_scenario_is_one_line_exit_2(capsys):
    assert main(["evaluate", "--policy", "heuristic", "--scenario", "moon"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown scenario 'moon'" in err[0] and "paper-64" in err[0]


def test_cli_bad_number_and_missing_output_folder(capsys, tmp_path):
    assert main(["evaluate", "--policy", "heuristic", "--seeds", "0"]) == 2
    assert "allowed: a count >= 1" in capsys.readouterr().err
    assert main(["evaluate", "--policy", "heuristic", "--seeds", "1", "--out", str(tmp_path / "no" / "x.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_error_has_no_traceback_as_a_process():
    out = subprocess.run([sys.executable, "-m", "wfbench.cli", "evaluate", "--policy", "nope"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr and out.stderr.count("\n") == 1


def test_every_accepted_action_form_gives_the_same_episode(tiny):
    """int64 and float64 arrays take the compiled check; lists, int32, float32, read-only or
    strided arrays take the numpy path. All must be accepted alike and mean the same."""
    rng = np.random.default_rng(5)
    M, N = tiny.max_facilities, tiny.max_personnel
    steps = [(rng.integers(0, N + 1, size=(1, M)), rng.integers(0, 7, size=1), rng.random((1, 2, M)))
             for _ in range(40)]

    def forms(d, w, p):
        ro = d.copy()
        ro.flags.writeable = False
        strided = np.zeros((1, 2 * M), dtype=np.int64)[:, ::2]
        strided[...] = d
        yield {"dispatch": d, "workforce": w, "positioning": p}
        yield {"dispatch": d.tolist(), "workforce": w.tolist(), "positioning": p.tolist()}
        yield {"dispatch": d.astype(np.int32), "workforce": w.astype(np.int8), "positioning": p.astype(np.float32)}
        yield {"dispatch": ro, "workforce": w, "positioning": p}
        yield {"dispatch": strided, "workforce": w, "positioning": p}

    runs = []
    for k in range(5):
        s = Simulator(tiny, [3])
        s.reset()
        for d, w, p in steps:
            # float32 rounds the weights; give every form the same float32 weights
            p32 = p.astype(np.float32).astype(np.float64)
            s.step(list(forms(d, w, p32))[k])
        runs.append((s.state.series.copy(), s.state.counters.copy()))
    for series, counters in runs[1:]:
        assert np.array_equal(series, runs[0][0])
        assert np.array_equal(counters, runs[0][1])


def test_cli_bench_refuses_bad_options_before_measuring(capsys, tmp_path):
    assert main(["bench", "--json", str(tmp_path / "no" / "bench.json")]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and err.count("\n") == 1
    assert main(["bench", "--rounds", "0"]) == 2
    assert "allowed: an integer >= 1" in capsys.readouterr().err
