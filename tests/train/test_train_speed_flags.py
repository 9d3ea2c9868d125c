"""``benchmarks/train_speed.py`` takes ``--device``, ``--bf16`` and ``--compile`` (issue #44), and ``wfbench train``
trains the scale-free network when ``--model`` is not given.

The GPU rows of docs/performance.md come from the same script as the CPU ones. On this
CPU: a tiny bf16 run (the CUDA dtype path under CPU autocast) reports the same row as
before plus its settings; ``--compile`` and ``--device`` reach the trainer (compiling is
minutes on 2 cores, so its run is not made here).
"""

import json
import math

import pytest

from tests.conftest import load_script
from wfbench.cli import main as cli_main


@pytest.fixture(scope="module")
def train_speed():
    return load_script("benchmarks/train_speed.py")


def test_train_speed__bf16_runs_on_cpu_and_reports_the_usual_row(train_speed, tmp_path):
    out = tmp_path / "speed.json"
    rows = train_speed.main(["--scenario", "small", "--models", "scalefree", "--threads", "1", "--updates", "1",
                             "--num-envs", "4", "--num-steps", "4", "--bf16", "--json", str(out)])
    (r,) = rows
    assert r["bf16"] is True and r["compile"] is False and r["device"] == "cpu" and r["model"] == "scalefree"
    assert r["env_steps"] == 16 and math.isfinite(r["env_steps_per_s"]) and r["env_steps_per_s"] > 0
    assert {"simulator_share", "forward_share", "update_share", "obs_to_tensor_share"} <= r.keys()
    saved = json.loads(out.read_text())
    assert saved["machine"]["device"] == "cpu" and saved["rows"][0]["bf16"] is True


def test_train_speed__device_and_compile_reach_the_trainer(train_speed, monkeypatch):
    seen = {}

    class Stop(Exception):
        pass

    def fake_trainer(cfg, progress, log, amp):
        seen.update(device=cfg.device, compile=cfg.compile, bf16=cfg.bf16, amp=amp)
        raise Stop

    monkeypatch.setattr(train_speed, "Trainer", fake_trainer)
    with pytest.raises(Stop):
        train_speed.main(["--models", "paper", "--threads", "1", "--device", "cuda", "--bf16", "--compile"])
    import torch

    assert seen == {"device": "cuda", "compile": True, "bf16": True, "amp": torch.bfloat16}
    with pytest.raises(Stop):
        train_speed.main(["--models", "paper", "--threads", "1"])
    assert seen == {"device": "cpu", "compile": False, "bf16": False, "amp": None}


@pytest.mark.parametrize(("flags", "model"), [([], "scalefree"), (["--model", "small"], "small"),
                                              (["--variant", "dispatch"], "small"),
                                              (["--agents", "independent"], "small"),
                                              (["--algo", "impala", "--set", "mode=sync"], "scalefree")])
def test_train__without_model_trains_the_scalefree_network_where_the_trainer_can(tmp_path, flags, model):
    run = tmp_path / "run"
    argv = ["train", "--scenario", "small", "--num-envs", "4", "--num-steps", "4", "--steps", "16",
            "--eval-every", "0", "--run-dir", str(run), "--no-progress", "--no-tensorboard", *flags]
    assert cli_main(argv) == 0
    assert json.loads((run / "config.json").read_text())["model"] == model
