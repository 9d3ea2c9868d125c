"""``wfbench.train.fit``: a run from Python writes what ``wfbench train`` writes, and refuses what it refuses."""

import json

import pytest
import torch

from wfbench.cli import main as cli_main
from wfbench.train import SettingsError, fit

SETTINGS = {"scenario": "small", "model": "tiny", "num_envs": 4, "num_steps": 8, "steps": 64, "epochs": 1,
            "eval_every": 2, "eval_seeds": "public:2", "checkpoint_every": 1, "seed": 5, "device": "cpu"}
FLAGS = ["--scenario", "small", "--model", "tiny", "--num-envs", "4", "--num-steps", "8", "--steps", "64",
         "--epochs", "1", "--eval-every", "2", "--eval-seeds", "public:2", "--checkpoint-every", "1", "--seed", "5",
         "--device", "cpu"]
# what differs between two runs of the same code: when and how long they ran
TIMING = {"train_wall_s"}


def _files(run):
    return sorted(str(p.relative_to(run)) for p in run.rglob("*"))


def _same_checkpoint(a, b) -> None:
    x, y = (torch.load(p, map_location="cpu", weights_only=False) for p in (a, b))
    assert x.keys() == y.keys(), a
    for key in x.keys() - TIMING:
        if key in ("model", "optimizer", "torch_rng", "generator", "value_optimizer"):
            continue
        assert x[key] == y[key], (a, key)
    assert x["model"].keys() == y["model"].keys()
    assert all(torch.equal(x["model"][k], y["model"][k]) for k in x["model"]), a
    if "torch_rng" in x:
        assert torch.equal(x["torch_rng"], y["torch_rng"]) and torch.equal(x["generator"], y["generator"])


@pytest.mark.slow
def test_fit_and_the_command_line_write_the_same_run_folder(tmp_path, monkeypatch, capsys):
    """The default folder (runs/ALGO-VARIANT-SCENARIO), the same files, config.json and checkpoints bit for bit."""
    (tmp_path / "api").mkdir()
    (tmp_path / "cli").mkdir()
    monkeypatch.chdir(tmp_path / "api")
    trainer = fit("ppo", progress=False, log=False, **SETTINGS)
    monkeypatch.chdir(tmp_path / "cli")
    assert cli_main(["train", "--algo", "ppo", *FLAGS, "--no-progress", "--no-tensorboard"]) == 0
    assert "in runs/ppo-joint-small" in capsys.readouterr().out
    api, cli = tmp_path / "api" / "runs" / "ppo-joint-small", tmp_path / "cli" / "runs" / "ppo-joint-small"
    assert trainer.run.dir == api.relative_to(tmp_path / "api") and trainer.run.global_step == 64
    assert _files(api) == _files(cli)
    assert {"config.json", "latest.pt", "best.pt", "checkpoints/update_000002.pt"} <= set(_files(api))
    assert json.loads((api / "config.json").read_text()) == json.loads((cli / "config.json").read_text())
    for name in _files(api):
        if name.endswith(".pt"):
            _same_checkpoint(api / name, cli / name)


def test_fit_writes_best_pt_when_no_evaluation_ran(tmp_path):
    trainer = fit("ppo", progress=False, log=False, **{**SETTINGS, "eval_every": 0}, run_dir=str(tmp_path / "r"))
    best = torch.load(tmp_path / "r" / "best.pt", weights_only=False)
    assert trainer.run.best["update"] is None, "the run's own best stays unset"
    assert best["best"]["selected"] is False and best["best"]["update"] == 2
    assert all(torch.equal(v, trainer.model.state_dict()[k]) for k, v in best["model"].items())


@pytest.mark.slow
def test_fit_resumes_and_refuses_what_wfbench_train_refuses(tmp_path):
    run = tmp_path / "r"
    fit("ppo", progress=False, log=False, **SETTINGS, run_dir=str(run))
    with pytest.raises(SettingsError, match="has no optimizer state"):
        fit(resume=run / "best.pt", progress=False, log=False)
    with pytest.raises(SettingsError, match=r"is a ppo run, not --algo impala"):
        fit("impala", resume=run / "latest.pt", progress=False, log=False)
    with pytest.raises(SettingsError, match=r"--resume keeps the run's settings; these differ from it: lr, seed"):
        fit(resume=run / "latest.pt", progress=False, log=False, seed=6, lr=1e-3, steps=96)
    with pytest.raises(SettingsError, match=r"ppo has no setting 'rho_bar'; allowed: scenario, "):
        fit("ppo", progress=False, log=False, rho_bar=0.9)
    with pytest.raises(SettingsError, match=r"gamma = 1.5 is not allowed; allowed: a number in \(0, 1\]"):
        fit("ppo", progress=False, log=False, gamma=1.5, run_dir=str(tmp_path / "x"))
    assert not (tmp_path / "x").exists(), "a refused run writes nothing"
    resumed = fit(resume=run / "latest.pt", progress=False, log=False, steps=96)
    assert resumed.update == 3 and resumed.run.global_step == 96 and resumed.run.config.seed == 5
