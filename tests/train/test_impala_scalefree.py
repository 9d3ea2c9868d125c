"""IMPALA trains the scale-free network (issue #44): ``--algo impala --model scalefree``, as PPO does.

- a short sync run on ``small``: finite losses, the parameters move, the learner's
  log-probabilities of the actor's own actions are the actor's (lag 0: pi = mu, so the
  scale-free dispatch rows of the T steps are cut from the T + 1 rows right);
- the checkpoint is a deployable policy that reads observation version 2 and plays
  through ``wfbench.evaluate``; the same seed twice gives the same bits;
- the Ray path's actor (:class:`wfbench.train.impala.RemoteActor`, built here without Ray)
  builds the scale-free network too;
- the command line no longer refuses it; what stays refused says so in one line.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from wfbench.policies.neural import scalefree  # noqa: E402

from tests.train.scalefree_checks import assert_trained_and_plays  # noqa: E402
from wfbench.train.hindsight import HindsightConfig  # noqa: E402
from wfbench.train.impala import ImpalaConfig, RemoteActor, Trainer  # noqa: E402

pytestmark = pytest.mark.slow  # trains a network


def _cfg(tmp_path, **kw):
    base = dict(scenario="small", model="scalefree", num_envs=4, num_steps=8, steps=4 * 8 * 3, eval_every=0,
                checkpoint_every=100, run_dir=str(tmp_path / "run"), seed=3, mode="sync", sync_every=2)
    return ImpalaConfig(**{**base, **kw})


def _train(tmp_path, name: str) -> tuple[Trainer, list[dict]]:
    tr = Trainer(_cfg(tmp_path / name), progress=False, log=False)
    assert isinstance(tr.model, scalefree.ScaleFreeNet) and isinstance(tr.actor.model, scalefree.ScaleFreeNet)
    stats = [tr.train(updates=1) for _ in range(3)]
    return tr, stats


def test_impala_trains_the_scalefree_network_deterministically_and_deploys_it(tmp_path):
    a, stats = _train(tmp_path, "a")
    for s in stats:
        assert all(np.isfinite(v) for v in s.values()), s
    assert [s["policy_lag"] for s in stats] == [0, 1, 0]
    for s in stats:
        if s["policy_lag"] == 0:  # the learner rescores the actor's actions with the actor's parameters
            assert s["abs_log_rho"] < 1e-4, s
    b, _ = _train(tmp_path, "b")
    assert_trained_and_plays(a, b, "impala", tmp_path)


def test_the_ray_paths_actor_builds_the_scalefree_network(tmp_path):
    tr = Trainer(_cfg(tmp_path), progress=False, log=False)
    remote = RemoteActor(tr.run.config, 0, None, tr.run.scenario)  # the plain class Ray would run
    assert isinstance(remote.actor.model, scalefree.ScaleFreeNet)
    roll = remote.rollout(0, {k: v.detach().cpu() for k, v in tr.model.state_dict().items()})
    assert roll["version"] == 0 and roll["logp"].shape == (8, 4) and torch.isfinite(roll["logp"]).all()
    assert "context" in roll["raw"]  # observation version 2
    tr.learn(roll)  # the learner takes a rollout of another actor


def test_the_command_line_trains_it_and_refuses_what_stays_refused_in_one_line(tmp_path):
    run = tmp_path / "cli"
    r = subprocess.run([sys.executable, "-m", "wfbench.cli", "train", "--algo", "impala", "--model", "scalefree",
                        "--scenario", "small", "--steps", "32", "--num-envs", "4", "--num-steps", "8",
                        "--eval-every", "0", "--no-progress", "--no-tensorboard", "--run-dir", str(run)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "not trained by impala" not in r.stderr
    saved = json.loads((run / "config.json").read_text())
    assert saved["algo"] == "impala" and saved["model_config"]["arch"] == "scalefree"

    for cfg, message in [
        (_cfg(tmp_path, variant="dispatch"), "variant 'dispatch' is not allowed for impala; allowed: joint"),
        (_cfg(tmp_path, model_overrides={"heads": 4}), r"unknown scalefree model setting\(s\) \['heads'\]"),
        (HindsightConfig(model="scalefree", scenario="small", variant="dispatch"), "variant 'dispatch' is not allowed"),
    ]:
        with pytest.raises(ValueError, match=message) as exc:
            cfg.validate()
        assert "\n" not in str(exc.value)
