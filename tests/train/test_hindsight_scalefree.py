"""Hindsight learning trains the scale-free network (issue #44): ``--algo hindsight --model scalefree``.

- a short run on ``small``: finite losses, the parameters move, the same seed twice gives
  the same bits, and the checkpoint reads observation version 2 and plays through
  ``wfbench.evaluate``;
- the scale-free dispatch chooses among the k nearest eligible people: a label naming
  someone else is left out of the imitation loss (a row whose labels are all outside adds
  nothing) and counted in the run's statistics, as many as the stored features show;
- a heads-only run moves the scale-free heads it trains and nothing else; across worlds
  the stored observations are version 2's (the context too), padded to the largest world;
- the command line trains it, and ``wfbench train --algo hindsight`` without ``--model`` trains it too.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from wfbench.policies.neural import scalefree  # noqa: E402

from tests.train.scalefree_checks import assert_trained_and_plays  # noqa: E402
from wfbench.train.hindsight import (  # noqa: E402
    SCALEFREE_HEAD_MODULES,
    HindsightConfig,
    Trainer,
    outside_candidates,
    scalefree_label_log_probs,
)

pytestmark = pytest.mark.slow  # trains a network

BASE = dict(scenario="small", model="scalefree", device="cpu", num_envs=2, num_steps=8, burn_in=2, iter_steps=32,
            steps=2 * 8 * 2 * 3, grad_steps=3, batch_seqs=4, eval_every=0, checkpoint_every=100, seed=5)


def _cfg(tmp_path, **kw):
    return HindsightConfig(**{**BASE, "run_dir": str(tmp_path / "run"), **kw})


def _train(tmp_path, **kw) -> tuple[Trainer, dict]:
    tr = Trainer(_cfg(tmp_path, **kw), progress=False, log=False)
    assert isinstance(tr.model, scalefree.ScaleFreeNet)
    return tr, tr.train()


def test_hindsight_trains_the_scalefree_network_deterministically_and_deploys_it(tmp_path):
    a, stats = _train(tmp_path / "a")
    assert a.iteration == 3
    assert all(np.isfinite(v) for v in stats.values()), stats
    assert stats["labels_outside_k"] >= 0 and 0.0 <= stats["outside_k_share"] <= 1.0
    b, _ = _train(tmp_path / "b")
    assert_trained_and_plays(a, b, "hindsight", tmp_path)


def test_labels_outside_the_k_candidates_are_counted_and_left_out_of_the_loss(tmp_path):
    # one candidate per facility and the full oracle's dispatch: some labels name someone other than the nearest
    tr = Trainer(_cfg(tmp_path, teacher="oracle", model_overrides={"k": 1}, num_envs=3, num_steps=40),
                 progress=False, log=False)
    res = tr.collect(beta=1.0)
    tr.data.add(res["chunk"])
    batch = tr.data.batch(torch.arange(3), tr.run.device)  # time major, as the update reads it
    x = scalefree.features(tr.model, {k: batch[k].flatten(0, 1) for k in scalefree.OBS_KEYS_V2})
    acts = {k: batch[k].flatten(0, 1).long() for k in ("dispatch", "workforce", "positioning")}
    outside = outside_candidates(x, acts["dispatch"])
    st = res["stats"]
    assert st["labels_outside_k"] == int(outside.sum()) > 0
    assert st["label_dispatches"] > st["labels_outside_k"]

    with torch.no_grad():
        out, _ = tr.model(x, (batch["h"], batch["c"]), batch["starts"])
    logp = scalefree_label_log_probs(tr.model, out, x, acts)["dispatch"]
    choosing = x["choose"]
    all_out = choosing.any(-1) & (outside == choosing).all(-1)
    inside = choosing.any(-1) & ~outside.any(-1)
    assert all_out.any() and inside.any()
    assert (logp[all_out] == 0).all()  # no candidate list expresses those labels: nothing learned from them
    assert (logp[inside] < 0).all()  # a label the network can pick: its log-probability, below 0


def test_a_heads_only_run_moves_only_the_scalefree_heads_it_trains(tmp_path):
    tr = Trainer(_cfg(tmp_path, train_params="heads", dispatch_weight=0.0, positioning_weight=0.0),
                 progress=False, log=False)
    before = {k: v.clone() for k, v in tr.model.state_dict().items()}
    tr.train(iterations=1)
    moved = {k.split(".")[0] for k, v in tr.model.state_dict().items() if not torch.equal(v, before[k])}
    assert moved == set(SCALEFREE_HEAD_MODULES["workforce"]), moved
    names = {n.split(".")[0] for n, _ in tr.model.named_parameters()}
    assert {m for ms in SCALEFREE_HEAD_MODULES.values() for m in ms} <= names


def test_across_worlds_it_stores_the_version_2_observation_padded(tmp_path):
    tr = Trainer(_cfg(tmp_path, scenario="paper-64", scenarios="small,table2-g32-f25-s10", steps=432, iter_steps=16,
                      grad_steps=1, batch_seqs=2), progress=False, log=False)
    stats = tr.train()
    assert all(np.isfinite(v) for v in stats.values()), stats
    assert tr.world.name == "table2-g32-f25-s10-v1", "after small's 200 steps, the next world"
    data = tr.data.data
    assert data["context"].shape[2] == scalefree.N_CONTEXT and data["facilities"].shape[2] == 50
    small = data["facility_mask"][:2]  # the first chunk is small's: 8 slots, padded to 50
    assert small[..., :8].any() and not small[..., 8:].any()
    assert set(data["dispatch"][:2, :, 8:].unique().tolist()) == {50}, "a padded facility's label is the no-op"


def test_the_command_line_trains_it_and_by_default(tmp_path):
    for name, model in (("given", ["--model", "scalefree"]), ("default", [])):
        run = tmp_path / name
        r = subprocess.run([sys.executable, "-m", "wfbench.cli", "train", "--algo", "hindsight", *model,
                            "--scenario", "small", "--steps", "32", "--num-envs", "2", "--num-steps", "8",
                            "--set", "iter_steps=16", "--set", "grad_steps=2", "--set", "burn_in=2",
                            "--eval-every", "0", "--no-progress", "--no-tensorboard", "--run-dir", str(run)],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        saved = json.loads((run / "config.json").read_text())
        assert saved["algo"] == "hindsight" and saved["model_config"]["arch"] == "scalefree", name
