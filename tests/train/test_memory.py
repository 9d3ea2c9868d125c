"""The PPO update's memory (issue #44): the estimate against what autograd keeps, and the chunked update.

``paper`` at B = 4096 ran out of a GPU's memory: the update keeps the activations of a
whole minibatch (B / minibatches environments x T steps) for its backward pass, about
2.3 MB a row on paper-64. :func:`wfbench.train.memory.row_bytes` estimates that; here it is
checked against the bytes autograd saves (``saved_tensors_hooks``, the parameters left
out) on CPU at small sizes. The bound: an update in chunks of ``update_envs``
environments gives the whole minibatch's step (the same weights up to float rounding)
while only a chunk's activations are alive.
"""

import os
import platform
import subprocess
import sys

import pytest
import torch
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.model import model_config

import wfbench
from wfbench import policies
from wfbench.train import memory
from wfbench.train.ppo import TrainConfig, Trainer


def _obs(scenario: str, B: int):
    sim = wfbench.Simulator(wfbench.scenario(scenario), list(range(B)))
    obs = sim.reset()
    h = policies.get("heuristic")
    h.reset(list(range(B)))
    for _ in range(10):
        obs = sim.step_observe(h.act(obs))[1]
    return obs


def _saved_bytes_per_row(net, obs, B: int) -> float:
    """What autograd keeps for the backward pass of one forward (parameters aside), per row."""
    params = {p.untyped_storage().data_ptr() for p in net.parameters()}
    seen = {}

    def pack(t):
        st = t.untyped_storage()
        if st.data_ptr() not in params:
            seen[(st.data_ptr(), st.nbytes())] = st.nbytes()
        return t

    x = scalefree.features(net, scalefree.raw_tensors(net, obs))
    with torch.autograd.graph.saved_tensors_hooks(pack, lambda t: t):
        net(x, net.initial_state(B), torch.ones(1, B))
    return sum(seen.values()) / B


@pytest.mark.parametrize("scenario", ["small", "paper-64"])
def test_memory__the_estimate_is_within_15_percent_of_what_autograd_keeps(scenario):
    B = 6
    obs = _obs(scenario, B)
    M, N = obs["requesting"].shape[1], obs["personnel"].shape[1]
    torch.manual_seed(0)
    configs = [model_config("paper"), model_config("tiny"), model_config("paper", d=48, heads=2, n_blocks=1, ff=4),
               scalefree.scalefree_config(), scalefree.scalefree_config(d=64, k=4)]
    for cfg in configs:
        net = scalefree.build_network(cfg.to_dict())
        measured = _saved_bytes_per_row(net, obs, B)
        assert memory.row_bytes(cfg, M, N) == pytest.approx(measured, rel=0.15), cfg
    # what grows: the attention blocks' entity rows, not the heads
    paper = model_config("paper")
    assert memory.row_bytes(paper, M, N) > 2 * memory.row_bytes(model_config("paper", n_blocks=0), M, N)
    assert memory.row_bytes(model_config("paper", heads=8), M, N) < 1.1 * memory.row_bytes(paper, M, N)


def test_memory__paper_64_at_b_4096_needs_chunks_within_80_gib():
    paper = model_config("paper")
    per_env = memory.update_bytes_per_env(paper, 50, 50, T=32, minibatches=2)
    assert 30 * 2**20 < per_env < 45 * 2**20  # the reported 35 MiB per environment
    assert per_env * 4096 > 80 * 2**30  # whole minibatches do not fit an H100 ...
    envs = memory.update_envs(paper, 50, 50, 32, budget_bytes=40 * 2**30)
    assert 0 < envs < 2048 and envs * 32 * memory.row_bytes(paper, 50, 50) <= 40 * 2**30  # ... chunks do


def _trainer(tmp_path, name, update_envs):
    cfg = TrainConfig(scenario="small", model="tiny", num_envs=8, num_steps=8, steps=8 * 8 * 4, eval_every=0,
                      checkpoint_every=10**9, run_dir=str(tmp_path / name), device="cpu", seed=5)
    return Trainer(cfg, progress=False, log=False, update_envs=update_envs)


def test_memory__a_chunked_update_takes_the_whole_minibatchs_step(tmp_path):
    whole, chunked = _trainer(tmp_path, "whole", None), _trainer(tmp_path, "chunked", 1)
    assert whole.update_envs is None  # on CPU "auto" is the whole minibatch
    assert _trainer(tmp_path, "auto", "auto").update_envs is None
    roll = whole.rollout()
    assert all(torch.equal(a, b) for a, b in zip(roll["logp"], chunked.rollout()["logp"], strict=True))
    calls = []
    chunked.model.register_forward_pre_hook(lambda m, args: calls.append(args[2].shape[1]))
    s_whole, s_chunked = whole.learn(roll), chunked.learn(roll)
    assert calls == [1] * 16  # 2 epochs x 2 minibatches x 4 environments, one at a time
    for (name, a), b in zip(whole.model.state_dict().items(), chunked.model.state_dict().values(), strict=True):
        assert torch.allclose(a, b, rtol=1e-4, atol=1e-6), name
    assert not all(torch.equal(a, b) for a, b in zip(whole.model.parameters(), _trainer(
        tmp_path, "fresh", None).model.parameters(), strict=True))  # the update moved the weights
    for k in ("pg_loss", "v_loss", "entropy", "approx_kl", "clipfrac", "ent_workforce"):
        assert s_chunked[k] == pytest.approx(s_whole[k], rel=1e-4, abs=1e-7), k
    with pytest.raises(ValueError, match="update_envs"):
        _trainer(tmp_path, "bad", 0)


_FAULTS = """
import resource, sys
import torch
from wfbench.train.memory import keep_freed_memory
kept = keep_freed_memory()
def minibatch():  # an update's activations: blocks of megabytes, allocated, written and freed
    blocks = [torch.empty(2 << 20).fill_(1.0) for _ in range(4)]
    del blocks
minibatch(); minibatch()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(5):
    minibatch()
print(kept, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
                    reason="glibc's malloc only")
@pytest.mark.slow
def test_keep_freed_memory__the_next_minibatch_reuses_the_freed_blocks_without_page_faults():
    # glibc's defaults hand the freed top of the heap back and fault the pages in again (5 x 32 MiB here: about
    # 40,000 faults); kept, the blocks are reused (0 to 2,048 faults seen: the heap's growth once). The user's
    # MALLOC_* setting is left alone.
    env = {k: v for k, v in os.environ.items() if k not in memory.MALLOC_ENV}
    run = [sys.executable, "-c", _FAULTS]
    kept, faults = subprocess.run(run, env=env, capture_output=True, text=True, check=True).stdout.split()
    assert kept == "True" and int(faults) < 8000
    mine = subprocess.run(run, env={**env, "MALLOC_TRIM_THRESHOLD_": str(1 << 20)}, capture_output=True, text=True,
                          check=True).stdout.split()
    assert mine[0] == "False" and int(mine[1]) > 20_000
