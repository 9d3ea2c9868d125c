"""Training across worlds (wfbench.train.worlds, ``wfbench train --scenarios``): one batch, several scenarios."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from wfbench import policies

torch = pytest.importorskip("torch")

from wfbench.policies.registry import ScenarioMismatchWarning, warn_if_trained_elsewhere  # noqa: E402

from wfbench.cli import main as cli_main  # noqa: E402
from wfbench.core.simulator import Simulator  # noqa: E402
from wfbench.train.worlds import Worlds, deal, resolve_worlds  # noqa: E402

TWO = "small,table2-g32-f25-s10"  # 8 + 8 slots, horizon 200, and 50 + 50 slots, horizon 800


def test_worlds__a_suite_split_or_a_list_and_never_a_held_out_scenario(tmp_path, capsys):
    names = [w.name for w in resolve_worlds("suite-v1:train")]
    assert names == ["small-v1", "paper-64-v1", "nonstationary-v1", "table2-g32-f25-s10-v1", "table2-g256-f25-s5-v1",
                     "surge-64-v1", "clustered-64-v1", "real-benelux-v1"]
    assert [w.name for w in resolve_worlds("paper-64, small,paper-64-v1")] == ["paper-64-v1", "small-v1"]
    assert list(deal(128, 8)) == [16] * 8 and list(deal(10, 4)) == [3, 3, 2, 2]
    for spec, says in (("suite-v1:heldout", "the heldout split is never trained on; allowed: suite-v1:train"),
                       ("small,large", "large-v1 is a held-out scenario of suite-v1 and is never trained on"),
                       ("suite-v1:tain", "unknown split 'tain' of suite-v1; allowed: suite-v1:train"),
                       ("small,,paper-64", "allowed: a comma-separated list of scenarios and suite splits")):
        assert cli_main(["train", "--scenarios", spec, "--run-dir", str(tmp_path / "x"), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert says in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not (tmp_path / "x").exists(), "a refused run writes nothing"
    assert cli_main(["train", "--scenarios", TWO, "--variant", "dispatch", "--run-dir", str(tmp_path / "x"),
                     "--no-progress"]) == 2
    assert "allowed: variant joint" in capsys.readouterr().err


def _padded_action(action: dict, sim: Simulator, M: int, N: int) -> dict:
    d = np.full((sim.B, M), N, dtype=np.int64)
    d[:, :sim.M] = np.where(action["dispatch"] >= sim.N, N, action["dispatch"])
    p = np.zeros((sim.B, 2, M))
    p[:, :, :sim.M] = action["positioning"]
    return {"dispatch": d, "workforce": np.asarray(action["workforce"]), "positioning": p}


def test_worlds__the_batch_steps_exactly_as_its_worlds_apart_with_empty_padding():
    worlds = resolve_worlds(TWO)
    seeds = [[1_000_000, 1_000_001], [1_000_002]]
    batch = Worlds(worlds, seeds)
    apart = [Simulator(w.config, s, keep_series=False, threads=1) for w, s in zip(worlds, seeds, strict=True)]
    heuristics = [policies.get("heuristic") for _ in apart]
    obs = batch.reset()
    own = [sim.reset() for sim in apart]
    for h, sim in zip(heuristics, apart, strict=True):
        h.reset(sim.seeds)
    assert (batch.B, batch.M, batch.N) == (3, 50, 50) and list(batch.horizons) == [200, 200, 800]
    for _ in range(30):
        actions = [h.act(o) for h, o in zip(heuristics, own, strict=True)]
        joined = [_padded_action(a, sim, batch.M, batch.N) for a, sim in zip(actions, apart, strict=True)]
        step = {k: np.concatenate([j[k] for j in joined]) for k in joined[0]}
        rewards, obs = batch.step_observe(step)
        parts = [sim.step_observe(a) for sim, a in zip(apart, actions, strict=True)]
        own = [o for _, o in parts]
        assert np.array_equal(rewards, np.concatenate([r for r, _ in parts]))
        small = own[0]
        assert np.array_equal(obs["facilities"][:2, :8], small["facilities"])
        assert np.array_equal(obs["personnel"][:2, :8], small["personnel"])
        assert np.array_equal(obs["dispatch_mask"][:2, :8, :8], small["dispatch_mask"][:, :, :8])
        assert np.array_equal(obs["dispatch_mask"][:2, :8, 50], small["dispatch_mask"][:, :, 8]), "the no-op column"
        for key in ("facility_mask", "personnel_mask", "requesting", "dispatchable"):
            assert not obs[key][:2, 8:].any(), f"{key}: a padded slot of small is not empty"
        assert np.array_equal(obs["facilities"][2:], own[1]["facilities"])
    assert np.array_equal(batch.state.t, [30, 30, 30])
    batch.reset(indices=[1], seeds=[7])
    assert list(batch.seeds) == [1_000_000, 7, 1_000_002] and list(batch.state.t) == [30, 0, 30]


def _cfg(tmp_path, **kw):
    from wfbench.train.ppo import TrainConfig

    base = dict(scenarios=TWO, model="tiny", num_envs=4, num_steps=8, steps=64, epochs=1, eval_every=2,
                eval_seeds="public:1", checkpoint_every=100, run_dir=str(tmp_path), device="cpu")
    return TrainConfig(**{**base, **kw})


@pytest.mark.slow
def test_worlds__ppo_across_worlds_normalizes_per_world_reproduces_and_knows_its_worlds(tmp_path):
    from wfbench.train.ppo import Trainer

    weights = []
    for i in range(2):
        tr = Trainer(_cfg(tmp_path / str(i)), progress=False, log=False)
        tr.train()
        weights.append({k: v.clone() for k, v in tr.model.state_dict().items()})
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0]), "the same seed, other weights"
    env = tr.env
    assert list(env.sim.world) == [0, 0, 1, 1]
    assert [round(r.count) for r in env.world_mean] == [32, 32], "each world's statistics count its own steps"
    assert env.world_mean[0].mean != env.world_mean[1].mean
    latest = torch.load(tmp_path / "1" / "latest.pt", weights_only=False)
    assert latest["scenario"] == TWO and latest["worlds"] == ["small-v1", "table2-g32-f25-s10-v1"]
    public = latest["history"][-1]
    assert public["scale"] == "normalized" and set(public["worlds"]) == {"small-v1", "table2-g32-f25-s10-v1"}
    assert public["sample"] == pytest.approx(np.mean(list(public["worlds"].values())))
    # resuming restores the per-world normalizers with the rest
    resumed = Trainer(_cfg(tmp_path / "1", steps=96), resume=tmp_path / "1" / "latest.pt", progress=False, log=False)
    assert [vars(r) for r in resumed.env.world_std] == [vars(r) for r in env.world_std]
    # deployed: at home on its worlds, zero-shot elsewhere
    policy = policies.get(f"ppo:{tmp_path / '1' / 'best.pt'}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not warn_if_trained_elsewhere(policy, "small")
        assert not warn_if_trained_elsewhere(policy, "table2-g32-f25-s10-v1")
    with pytest.warns(ScenarioMismatchWarning, match="none of them: zero-shot"):
        assert warn_if_trained_elsewhere(policy, "large")


@pytest.mark.slow
def test_worlds__hindsight_learning_takes_the_worlds_in_turn(tmp_path):
    from wfbench.train.hindsight import HindsightConfig, Trainer

    cfg = HindsightConfig(scenarios=TWO, model="tiny", num_envs=2, num_steps=8, burn_in=2, iter_steps=16, steps=432,
                          teacher="nearest+oracle+oracle", grad_steps=1, batch_seqs=2, eval_every=0,
                          checkpoint_every=100, run_dir=str(tmp_path), device="cpu")
    tr = Trainer(cfg, progress=False, log=False)
    tr.train()
    assert tr.world.name == "table2-g32-f25-s10-v1", "after small's 200 steps, the next world"
    data = tr.data.data
    assert data["facilities"].shape[2] == 50 and data["dispatch"].shape[2] == 50
    small = data["facility_mask"][:2]  # the first chunk is small's: 8 slots, padded to 50
    assert small[..., :8].any() and not small[..., 8:].any()
    assert set(data["dispatch"][:2, :, 8:].unique().tolist()) == {50}, "a padded facility's label is the no-op"


def test_across_worlds_ppo_takes_16_environments_a_world_unless_told(tmp_path):
    import json

    from wfbench.cli.train import default_num_envs
    from wfbench.train.hindsight import HindsightConfig
    from wfbench.train.ppo import TrainConfig

    assert default_num_envs(TrainConfig, {"scenarios": "suite-v1:train"}) == 128
    assert default_num_envs(TrainConfig, {"scenario": "small"}) is None, "one world: the config's 32"
    assert default_num_envs(HindsightConfig, {"scenarios": TWO}) is None, "its batches take the worlds in turn"
    for name, given, envs in (("default", [], 32), ("given", ["--num-envs", "4"], 4)):
        run = tmp_path / name
        assert cli_main(["train", "--scenarios", TWO, "--model", "tiny", *given, "--num-steps", "4",
                         "--steps", str(4 * envs), "--epochs", "1", "--minibatches", "1", "--eval-every", "0",
                         "--no-progress", "--no-tensorboard", "--run-dir", str(run)]) == 0
        saved = json.loads((run / "config.json").read_text())
        assert saved["num_envs"] == envs, name
