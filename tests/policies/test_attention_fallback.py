"""Attention falls back to the math kernel where a fused backend refuses a shape (issue #44), tested on CPU.

On CUDA cuDNN's attention refused the ``paper`` network's shapes at B = 4096 in bf16
(``Expected mha_graph.execute(...).is_good() to be true``). ``model.attention`` retries
such a call under ``sdpa_kernel(SDPBackend.MATH)``. Here a fake backend refuses every call
made while a fused kernel is allowed, so the fallback is what runs: the network's outputs
and gradients equal those of the math kernel, the refused shapes go to it directly
afterwards, and without a refusal the call is the plain one, bit for bit.
"""

import pytest
import torch
import torch.nn.functional as F
from torch.nn.attention import SDPBackend, sdpa_kernel
from wfbench.policies.neural import model as model_mod
from wfbench.policies.neural.model import WorkforceNet, featurize, model_config, obs_to_torch

import wfbench
from wfbench import policies

REAL = F.scaled_dot_product_attention
REFUSAL = "Expected mha_graph.execute(handle, variant_pack, workspace_ptr.get()).is_good() to be true"


@pytest.fixture
def refusing(monkeypatch):
    """F.scaled_dot_product_attention refusing every call while a fused backend is enabled; counts refusals."""
    calls = {"refused": 0, "math": 0}

    def fake(*args, **kwargs):
        if torch.backends.cuda.flash_sdp_enabled() or torch.backends.cuda.cudnn_sdp_enabled():
            calls["refused"] += 1
            raise RuntimeError(REFUSAL)
        calls["math"] += 1
        return REAL(*args, **kwargs)

    monkeypatch.setattr(F, "scaled_dot_product_attention", fake)
    monkeypatch.setattr(model_mod, "_MATH_ONLY", set())
    return calls


@pytest.fixture(scope="module")
def batch():
    sim = wfbench.Simulator(wfbench.scenario("small"), [0, 1, 2])
    obs = sim.reset()
    h = policies.get("heuristic")
    h.reset([0, 1, 2])
    for _ in range(30):
        obs = sim.step_observe(h.act(obs))[1]
    torch.manual_seed(0)
    net = WorkforceNet(model_config("tiny"))
    x = featurize(obs_to_torch(obs), net.config.coord_scale)
    return net, x, obs["t"].shape[0]


def _forward_backward(net, x, B):
    net.zero_grad(set_to_none=True)
    out, _ = net(x, net.initial_state(B), torch.ones(1, B))
    (out["value"].sum() + out["workforce"].square().sum()).backward()
    return out, {n: p.grad.clone() for n, p in net.named_parameters() if p.grad is not None}


def test_attention__a_refused_call_runs_the_math_kernel_with_its_outputs_and_gradients(refusing, batch):
    net, x, B = batch
    out, grads = _forward_backward(net, x, B)
    n_attention = 4 * net.config.n_blocks + 2 * net.config.n_fusion
    # the first call of each shape was refused (self-attention and the cross-attention with its bias: two), every
    # call ran on the math kernel, the refused retried there and the later ones of the same shape sent there directly
    assert refusing["refused"] == len(model_mod._MATH_ONLY) == 2
    assert refusing["math"] == n_attention
    with sdpa_kernel(SDPBackend.MATH):
        ref_out, ref_grads = _forward_backward(net, x, B)
    for k in out:
        assert torch.equal(out[k], ref_out[k]), k
    assert grads.keys() == ref_grads.keys() and all(torch.equal(grads[k], ref_grads[k]) for k in grads)
    assert all(torch.isfinite(g).all() for g in grads.values())
    # the refused shapes go to the math kernel directly: no second refusal
    refused = refusing["refused"]
    _forward_backward(net, x, B)
    assert refusing["refused"] == refused


def test_attention__a_call_no_backend_refuses_is_the_plain_one(batch, monkeypatch):
    monkeypatch.setattr(model_mod, "_MATH_ONLY", set())
    g = torch.Generator().manual_seed(1)
    q, k, v = (torch.randn(3, 2, 5, 8, generator=g) for _ in range(3))
    mask = torch.zeros(3, 1, 1, 5).masked_fill(torch.rand(3, 1, 1, 5, generator=g) < 0.3, float("-inf"))
    mask[..., 0] = 0.0
    assert torch.equal(model_mod.attention(q, k, v, mask), REAL(q, k, v, attn_mask=mask))
    assert not model_mod._MATH_ONLY


def test_attention__an_error_of_the_math_kernel_too_is_raised(refusing):
    q = torch.randn(2, 2, 5, 8)
    with pytest.raises(RuntimeError):
        model_mod.attention(q, q, q, torch.zeros(2, 1, 1, 7))  # a mask of the wrong length: no kernel takes it
