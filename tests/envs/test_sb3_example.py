"""examples/sb3_maskable_ppo.py runs: MaskablePPO trains through the batched adapter and wfbench scores it."""

import importlib.util
import math
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "sb3_maskable_ppo.py"


@pytest.mark.slow
def test_the_maskable_ppo_example_trains_and_is_scored(capsys):
    spec = importlib.util.spec_from_file_location("sb3_maskable_ppo", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(["--timesteps", "4096", "--envs", "16", "--eval-seeds", "5"])
    assert out["env_steps"] >= 4096
    for name in ("maskable-ppo", "random dispatch", "heuristic"):
        assert 0.0 < out[name] <= 1.0 and math.isfinite(out[name]), (name, out[name])
    printed = capsys.readouterr().out
    assert "env-steps/s" in printed and "maskable-ppo" in printed
