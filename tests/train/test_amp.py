"""The trainers' CUDA dtype path, run on CPU (issue #44): the same code under ``torch.autocast("cpu", ...)``.

On CUDA ``wfbench train`` runs its forward passes under bf16 autocast; the scale-free
network crashed there (``mat1 and mat2 must have the same dtype, but got Half and
Float``: cuDNN's autocast runs the LSTM in float16, and the positioning head, called after
the forward outside autocast, met a float32 weight). ``Trainer(config, amp=dtype)`` runs the
very same trainer code under autocast on the CPU, which is how CI tests it without a GPU:

- one PPO rollout and update of the scale-free and the paper network under bfloat16 and
  float16 autocast: finite losses close to the float32 ones (autocast was on: not equal),
  the heads in float32;
- the LSTM runs in float32 with autocast off (cuDNN's autocast runs RNNs in float16
  whatever the autocast dtype: the crash's "Half");
- the float32 default: no autocast on CPU, bf16 on CUDA only, a wrong dtype refused.
"""

import math

import pytest
import torch
from wfbench.policies.neural import scalefree

from wfbench.train.ppo import TrainConfig, Trainer
from wfbench.train.precision import amp_dtype, autocast


def _trainer(tmp_path, model: str, amp) -> Trainer:
    cfg = TrainConfig(scenario="small", model=model, num_envs=8, num_steps=16, steps=8 * 16 * 4, eval_every=0,
                      checkpoint_every=10**9, run_dir=str(tmp_path / f"{model}-{amp}"), device="cpu", seed=3)
    return Trainer(cfg, progress=False, log=False, amp=amp)


@pytest.fixture(scope="module")
def float32_stats(tmp_path_factory):
    """The losses of one float32 update per network: what the autocast runs are compared with."""
    tmp = tmp_path_factory.mktemp("fp32")
    out = {}
    for model in ("scalefree", "paper"):
        tr = _trainer(tmp, model, None)
        out[model] = tr.learn(tr.rollout())
    return out


@pytest.mark.slow
@pytest.mark.parametrize("model", ["scalefree", "paper"])
@pytest.mark.parametrize("dtype", [torch.bfloat16, torch.float16])
def test_amp__one_ppo_update_under_cpu_autocast_has_finite_losses_near_float32(tmp_path, model, dtype,
                                                                              float32_stats):
    tr = _trainer(tmp_path, model, dtype)
    assert tr.run.amp is dtype and tr.env.amp is dtype
    roll = tr.rollout()
    assert roll["logp"].dtype == torch.float32 and roll["value"].dtype == torch.float32
    stats = tr.learn(roll)
    for k in ("pg_loss", "v_loss", "entropy", "approx_kl"):
        assert math.isfinite(stats[k]), (k, stats[k])
    assert stats["ent_dispatch"] > 0  # the dispatch pointer ran (facilities with a choice in the rollout)
    ref = float32_stats[model]
    assert stats != ref  # autocast was on: lower precision moves the losses ...
    assert stats["v_loss"] == pytest.approx(ref["v_loss"], rel=0.05)  # ... but not far
    assert stats["entropy"] == pytest.approx(ref["entropy"], rel=0.05)
    # the heads stay float32 under autocast
    x = scalefree.features(tr.model, {k: v[:1] for k, v in roll["raw"].items()})
    x = {k: v.flatten(0, 1) for k, v in x.items()}
    with torch.no_grad(), autocast(tr.run.device, dtype):
        out, _ = tr.net(x, tuple(s for s in roll["init_state"]), roll["starts"][:1])
    assert out["value"].dtype == torch.float32 and out["dispatch"].dtype == torch.float32
    assert out["workforce"].dtype == torch.float32


@pytest.mark.slow
@pytest.mark.parametrize("model", ["scalefree", "paper"])
def test_amp__the_lstm_runs_in_float32_outside_autocast(tmp_path, model):
    """cuDNN's autocast would run the LSTM in float16 whatever the autocast dtype (the reported crash's Half).

    So the networks run their memory with autocast off, in float32: checked at the LSTM's
    call, in the rollout and in the update, and the carried state stays float32.
    """
    tr = _trainer(tmp_path, model, torch.bfloat16)
    seen = []
    lstm = tr.model.lstm

    def record(module, args):
        z, (h, c) = args
        seen.append((torch.is_autocast_enabled("cpu"), z.dtype, h.dtype, c.dtype))

    handle = lstm.register_forward_pre_hook(record)
    try:
        roll = tr.rollout()
        assert all(s.dtype == torch.float32 for s in tr.env.state)
        n = len(seen)
        tr.learn(roll)
    finally:
        handle.remove()
    assert n >= tr.run.config.num_steps and len(seen) > n  # the rollout's steps and the update's reruns
    assert set(seen) == {(False, torch.float32, torch.float32, torch.float32)}


def test_amp__float32_on_cpu_bf16_on_cuda_by_default():
    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    assert amp_dtype(cpu, True) is None
    assert amp_dtype(cuda, True) is torch.bfloat16
    assert amp_dtype(cuda, False) is None
    assert amp_dtype(cpu, False, "float16") is torch.float16
    assert amp_dtype(cuda, True, None) is None
    with pytest.raises(ValueError, match="allowed: auto, bfloat16, float16"):
        amp_dtype(cpu, True, "float8")
    assert not autocast(cpu, None)._enabled  # the float32 path: no autocast at all
    assert autocast(cpu, torch.bfloat16)._enabled
