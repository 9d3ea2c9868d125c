"""Tuning a policy's declared parameters (wfbench tune) and tuned-policy files as policies."""

import io
import json
from pathlib import Path

import optuna
import pandas as pd
import pytest
from wfbench.policies import tuned as tuned_file
from wfbench.policies.composite import Composite

from wfbench import policies
from wfbench.cli import main
from wfbench.envs.parallel import resolve_fixed
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate
from wfbench.scenarios.resolve import resolve_scenario
from wfbench.tune import check_tuning_seeds, search_space, tune
from wfbench.tune import search as tune_mod

SEEDS = "public:3"
SMALL = resolve_scenario("small").replace(horizon=60)
FEW = {"workforce.high": None, "workforce.cooldown": (2, 40), "positioning.request_weight": None}


def _run(tmp_path, trials, db="study.db", **kw):
    kw.setdefault("params", FEW)
    return tune("heuristic", SMALL, trials, seeds=SEEDS, study_db=tmp_path / db, execution=Execution(threads=1),
                out=kw.pop("out", tmp_path / "tuned.json"), **kw)


def test_a_tiny_study_writes_a_file_that_is_a_policy_everywhere(tmp_path):
    r = _run(tmp_path, 3)
    data = json.loads(r.path.read_text())
    assert data["format"] == "wfbench-tuned-policy" and data["base"] == "heuristic" and data["trials"] == 3
    assert data["seeds"] == [1000, 1001, 1002] and data["seed_set"] == "1000..1002 (3)"
    assert data["wfbench_version"] and "wfbench tune heuristic" in data["command"]
    assert set(FEW) <= set(data["params"]) and set(data["params"]) == set(policies.get("heuristic").tunable)
    assert 2 <= data["params"]["workforce.cooldown"] <= 40 and isinstance(data["params"]["workforce.cooldown"], int)
    # the first trial is the untuned policy, so the best is never worse on the tuning seeds
    untuned = evaluate("heuristic", SMALL, SEEDS)["nsw"].mean()
    assert r.untuned_score == pytest.approx(untuned, abs=1e-12) and r.tuned.best_score >= untuned
    # the file is a policy: by path and by tuned:path, compiled, scoring exactly what the search saw
    for spec in (str(r.path), f"tuned:{r.path}"):
        p = policies.get(spec)
        assert isinstance(p, Composite) and p.compiled and p.name == "heuristic-tuned"
        assert p.params() == pytest.approx(data["params"])
    assert evaluate(str(r.path), SMALL, SEEDS)["nsw"].mean() == pytest.approx(r.tuned.best_score, abs=1e-12)
    assert tuned_file.read(r.path).params == data["params"]


def test_an_interrupted_study_resumes_where_it_stopped(tmp_path, monkeypatch):
    real = tune_mod.evaluate
    calls = {"n": 0}

    def crash_on_third(*a, **kw):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*a, **kw)

    monkeypatch.setattr(tune_mod, "evaluate", crash_on_third)
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, 4)
    monkeypatch.setattr(tune_mod, "evaluate", real)
    study = optuna.load_study(study_name="heuristic@small", storage=f"sqlite:///{tmp_path / 'study.db'}")
    first = [t.params for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(first) == 2
    r = _run(tmp_path, 4)  # the same call again: only the missing trials run, in the same study
    assert r.new_trials == 2 and r.tuned.trials == 4
    study = optuna.load_study(study_name="heuristic@small", storage=f"sqlite:///{tmp_path / 'study.db'}")
    done = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert [t.params for t in done[:2]] == first and len(done) == 4
    assert len({tuple(sorted(t.params.items())) for t in done}) == 4  # the resumed sampler does not repeat itself
    again = _run(tmp_path, 4)
    assert again.new_trials == 0 and again.tuned == r.tuned
    assert _run(tmp_path, 5).new_trials == 1  # a larger total extends it


@pytest.mark.slow
def test_the_same_call_on_a_fresh_study_gives_the_same_file(tmp_path):
    a = _run(tmp_path, 4, db="a.db", out=tmp_path / "a.json")
    b = _run(tmp_path, 4, db="b.db", out=tmp_path / "b.toml")  # TOML by the suffix
    assert a.tuned.params == b.tuned.params and a.tuned.best_score == b.tuned.best_score
    assert tuned_file.read(b.path).params == a.tuned.params
    _run(tmp_path, 4, db="c.db", out=tmp_path / "c.json", sampler_seed=7)

    def proposals(db):
        return [t.params for t in optuna.load_study(study_name="heuristic@small", storage=f"sqlite:///{db}").trials]

    assert proposals(tmp_path / "a.db") == proposals(tmp_path / "b.db")
    assert proposals(tmp_path / "c.db")[0] == proposals(tmp_path / "a.db")[0]  # the untuned policy comes first
    assert proposals(tmp_path / "c.db")[1:] != proposals(tmp_path / "a.db")[1:]  # another sampler seed


@pytest.mark.parametrize("seeds", ["test", "0-2", [1000, 7], "60-62"])
def test_test_seeds_are_refused(tmp_path, seeds):
    with pytest.raises(ValueError, match="test seeds|no seed set meant for tuning"):
        tune("heuristic", SMALL, 2, seeds=seeds, study_db=tmp_path / "s.db")
    assert not (tmp_path / "s.db").exists()
    assert check_tuning_seeds("train:2") == [1_000_000, 1_000_001]


def test_a_file_tuned_on_test_seeds_is_refused(tmp_path):
    r = _run(tmp_path, 1)
    data = json.loads(r.path.read_text())
    data["seeds"] = [0, 1, 2]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"bad.json.*tuned on test seeds"):
        policies.get(str(bad))


@pytest.mark.parametrize("params, message", [
    ("workforce.foo", r"no tunable parameter 'workforce.foo'; allowed: workforce.high, workforce.low"),
    ("workforce.high=0.9:0.5", "low 0.9 must be below high 0.5"),
    ("workforce.high=0.1:0.5", r"\[0.1, 0.5\] is not allowed; allowed: within float in \[0.3, 1\]"),
    ("workforce.high=a:1", "low of workforce.high: 'a' is not a number"),
    ("workforce.high=0.5", "write it as name=low:high"),
    ("workforce.cooldown=1.5:9", "must be whole numbers"),
    (",", "no parameters named; allowed"),
])
def test_bad_parameter_names_and_ranges_say_what_is_allowed(params, message):
    with pytest.raises(ValueError, match=message):
        search_space(policies.get("heuristic"), params)


def test_bad_values_and_undeclaring_policies(tmp_path):
    h = policies.get("heuristic")
    with pytest.raises(ValueError, match=r"workforce.high = 1.5 is out of range; allowed: float in \[0.3, 1\]"):
        h.with_params({"workforce.high": 1.5})
    with pytest.raises(ValueError, match="workforce.cooldown = 2.5 is not a whole number"):
        h.with_params({"workforce.cooldown": 2.5})
    with pytest.raises(ValueError, match="no tunable parameter 'dispatch.revisit_cost'"):
        h.with_params({"dispatch.revisit_cost": 1.0})  # nearest dispatch has none; the solver's assignment has
    assert "dispatch.revisit_cost" in policies.get("solver").tunable
    with pytest.raises(ValueError, match="declares no tunable parameters"):
        tune("random", SMALL, 2, seeds=SEEDS, study_db=tmp_path / "s.db")
    with pytest.raises(ValueError, match="is a tuned-policy file: tune its base"):
        tune("x.json", SMALL, 2, seeds=SEEDS, study_db=tmp_path / "s.db")
    r = _run(tmp_path, 1)
    data = json.loads(r.path.read_text())
    data["params"]["workforce.bogus"] = 1
    (tmp_path / "p.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"p.json.*no tunable parameter 'workforce.bogus'"):
        policies.get(str(tmp_path / "p.json"))
    with pytest.raises(ValueError, match=r"missing.json': no such file"):
        policies.get(str(tmp_path / "missing.json"))
    (tmp_path / "other.json").write_text("{}")
    with pytest.raises(ValueError, match="not a tuned-policy file"):
        policies.get(str(tmp_path / "other.json"))


def test_a_study_refuses_other_settings_under_its_name(tmp_path):
    _run(tmp_path, 1)
    with pytest.raises(ValueError, match="was made with another seeds.*--study-name"):
        tune("heuristic", SMALL, 2, seeds="public:2", params=FEW, study_db=tmp_path / "study.db",
             out=tmp_path / "t.json")
    with pytest.raises(ValueError, match="another space"):
        _run(tmp_path, 2, params=["workforce.high"])


def test_the_shipped_tuned_policies_are_registered():
    assert {"heuristic-tuned", "solver-tuned"} <= set(policies.names())
    for name, base in (("heuristic-tuned", "heuristic"), ("solver-tuned", "solver")):
        p, b = policies.get(name), policies.get(base)
        t = p.tuned_from
        assert p.compiled and t.base == base and t.scenario == "paper-64" and t.seeds == list(range(1000, 1050))
        assert t.trials >= 60 and t.best_score > t.extra["untuned_score"]
        assert p.params() != b.params() and set(p.params()) == set(b.tunable)
        assert [part.code for part in p.parts.values()] == [part.code for part in b.parts.values()]
    assert evaluate("heuristic-tuned", "small", 1)["nsw"].notna().all()
    fixed = resolve_fixed({"workforce": "heuristic-tuned", "positioning": "solver-tuned"})
    assert fixed["workforce"].params() == policies.get("heuristic-tuned").params()
    with pytest.raises(ValueError, match="unknown policy 'nope' for fixed agent"):
        resolve_fixed({"workforce": "nope"})


def test_wfbench_policies_lists_the_tuned_ones(capsys):
    assert main(["policies"]) == 0
    out = capsys.readouterr().out
    assert "heuristic-tuned        policies/tuned/heuristic-paper-64.json" in out and "solver-tuned" in out


def test_wfbench_policies_lists_every_lookahead(capsys):
    from wfbench.policies.registry import lookahead_names

    assert main(["policies"]) == 0
    out = capsys.readouterr().out
    names = [line.split()[0] for line in out.splitlines() if " a lookahead on " in line]
    assert names == lookahead_names() and "rollout-solver-tuned" in names and "mpc-ma" in names, names


def test_cli_tune_writes_a_file_that_the_cli_evaluates(tmp_path, capsys):
    cfg = tmp_path / "small60.toml"
    cfg.write_text(SMALL.to_toml())
    out = tmp_path / "cli.json"
    argv = ["tune", "heuristic", "--scenario", str(cfg), "--trials", "2", "--seeds", SEEDS, "--params",
            "workforce.high,workforce.cooldown=2:40", "--study-db", str(tmp_path / "cli.db"), "--out", str(out),
            "--backend", "serial", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "heuristic-tuned: best mean NSW" in printed and f"wrote {out}" in printed
    data = json.loads(out.read_text())
    assert data["command"] == "wfbench " + " ".join(argv) and data["trials"] == 2
    assert main(argv) == 0 and "(0 new)" in capsys.readouterr().out  # resumed: nothing left to run
    assert main(["evaluate", "--policy", str(out), "--scenario", str(cfg), "--seeds", "1000-1002", "--backend",
                 "serial", "--no-progress", "--format", "csv"]) == 0
    nsw = pd.read_csv(io.StringIO(capsys.readouterr().out))["nsw"].mean()
    assert nsw == pytest.approx(data["best_score"], abs=1e-12)
    assert main(["tune", "heuristic", "--list"]) == 0 and "workforce.high" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["tune", "heuristic", "--seeds", "test"], "test seeds"),
    (["tune", "heuristic", "--seeds", "5"], "test seeds"),
    (["tune", "heuristic", "--params", "nope"], "no tunable parameter 'nope'; allowed"),
    (["tune", "heuristic", "--params", "workforce.low=0.5:0.2"], "must be below high"),
    (["tune", "random"], "declares no tunable parameters"),
    (["tune", "nopolicy"], "unknown policy 'nopolicy'"),
    (["tune", "heuristic", "--trials", "0"], "allowed: an integer >= 1"),
    (["tune", "heuristic", "--out", "/nonexistent/x.json"], "does not exist"),
    (["tune", "heuristic", "--out", "x.csv"], "allowed suffixes: .json, .toml"),
    (["tune", "heuristic", "--scenario", "nope"], "nope"),
    (["evaluate", "--policy", "missing.json"], "missing.json': no such file"),
    (["evaluate", "--policy", "tuned:missing.toml"], "missing.toml': no such file"),
])
def test_cli_mistakes_are_one_line_and_exit_2(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, *(["--study-db", "s.db"] if argv[0] == "tune" else [])]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: ") and message in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err and not (tmp_path / "s.db").exists()


def test_cli_ctrl_c_keeps_the_trials_and_the_same_command_resumes(tmp_path, monkeypatch, capsys):
    cfg = tmp_path / "small60.toml"
    cfg.write_text(SMALL.to_toml())
    argv = ["tune", "heuristic", "--scenario", str(cfg), "--trials", "3", "--seeds", SEEDS, "--params",
            "workforce.high", "--study-db", str(tmp_path / "c.db"), "--out", str(tmp_path / "c.json"),
            "--backend", "serial", "--no-progress"]
    real, calls = tune_mod.evaluate, {"n": 0}

    def ctrl_c_on_second(*a, **kw):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*a, **kw)

    monkeypatch.setattr(tune_mod, "evaluate", ctrl_c_on_second)
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "run the same command again to resume" in err and str(tmp_path / "c.db") in err
    assert not (tmp_path / "c.json").exists()
    monkeypatch.setattr(tune_mod, "evaluate", real)
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "3 trials (2 new)" in out
    study = out.split(" study ")[1].split(maxsplit=1)[0]  # the name tune() chose, as the summary prints it
    assert f"(study {study}): run the same command" in err


def test_tune_writes_the_command_s_default_file(tmp_path, monkeypatch, capsys):
    cfg = tmp_path / "small60.toml"
    cfg.write_text(SMALL.to_toml())
    api, cli = tmp_path / "api", tmp_path / "cli"
    api.mkdir(), cli.mkdir()
    monkeypatch.chdir(api)
    few = "workforce.high,workforce.cooldown=2:40"
    serial = Execution(threads=1)
    r = tune("heuristic", SMALL, 1, seeds=SEEDS, params=few, study_db=tmp_path / "api.db", execution=serial)
    assert r.path == tune_mod.default_out("heuristic", SMALL.name) == Path(f"tuned-heuristic-{SMALL.name}.json")
    monkeypatch.chdir(cli)
    assert main(["tune", "heuristic", "--scenario", str(cfg), "--trials", "1", "--seeds", SEEDS, "--params",
                 few, "--study-db", str(tmp_path / "cli.db"), "--backend", "serial", "--no-progress"]) == 0
    assert f"wrote {r.path};" in capsys.readouterr().out
    assert [p.name for p in api.iterdir()] == [p.name for p in cli.iterdir()] == [r.path.name]
    made = [json.loads((d / r.path).read_text()) for d in (api, cli)]
    assert [{k: m[k] for k in ("params", "searched", "scenario", "study_name")} for m in made] == \
        [{k: made[0][k] for k in ("params", "searched", "scenario", "study_name")}] * 2
    assert tune_mod.default_out("heuristic", "suite-v1:train").name == "tuned-heuristic-suite-v1-train.json"
    monkeypatch.chdir(tmp_path)
    tune("heuristic", SMALL, 1, seeds=SEEDS, params=few, study_db=tmp_path / "api.db", execution=serial, out=False)
    assert not list(tmp_path.glob("*.json")), "out=False writes no file"
