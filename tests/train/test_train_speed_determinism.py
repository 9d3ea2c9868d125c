"""The PPO trainer's speed-ups keep what is learned, bit for bit (issue #28, docs/performance.md "PPO training").

- a short ``paper-64`` run of the ``cpu`` preset twice: the same weights (test_rl checks
  the same on ``small``/``tiny``, which has no ``paper-64``-sized pointer and fewer rows);
- a run resumed from ``latest.pt``, twice: the same weights. A resumed run does not equal
  an uninterrupted one (the resume starts a fresh batch of environments on the next
  training seeds and a fresh LSTM state, by design: the simulator is not checkpointed),
  so that is not tested;
- the rewritten pieces against their former definitions, bitwise: the update's features
  computed once over the rollout against once per minibatch, the distance ``|dx| + |dy|``
  against the sum over a (B, M, N, 2) block, the pointer's distance prior
  ``(softplus * 8) * dist`` against ``(softplus * dist) * 8``, forward and backward.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from wfbench.policies.neural.model import featurize

from wfbench.train.ppo import TrainConfig, Trainer


def _cfg(run_dir, **kw) -> TrainConfig:
    base = dict(scenario="paper-64", model="cpu", num_envs=8, num_steps=8, steps=8 * 8 * 3, eval_every=0,
                checkpoint_every=10**9, device="cpu", threads=1, run_dir=str(run_dir), seed=11)
    return TrainConfig(**{**base, **kw})


def _weights(tr: Trainer) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in tr.model.state_dict().items()}


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def test_train_speed__paper64_cpu_preset_run_is_bit_identical_twice(tmp_path):
    runs = []
    for i in range(2):
        tr = Trainer(_cfg(tmp_path / str(i)), progress=False, log=False)
        tr.train()
        runs.append(_weights(tr))
    _assert_same(*runs)


def test_train_speed__a_resume_from_latest_pt_is_bit_identical_twice(tmp_path):
    first = Trainer(_cfg(tmp_path / "a"), progress=False, log=False)
    first.train(updates=1)
    latest = first.save(tmp_path / "a" / "latest.pt")
    runs = []
    for i in range(2):
        tr = Trainer(_cfg(tmp_path / f"r{i}"), resume=latest, progress=False, log=False)
        assert tr.update == 1
        tr.train()
        assert tr.update == 3
        runs.append(_weights(tr))
    _assert_same(*runs)
    assert any(not torch.equal(v, first.model.state_dict()[k]) for k, v in runs[0].items())


def test_train_speed__features_once_per_update_equal_features_per_minibatch(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=4), progress=False, log=False)
    roll = tr.rollout()
    scale = tr.run.network.coord_scale
    once = featurize({k: v[:-1] for k, v in roll["raw"].items()}, scale)
    idx = torch.tensor([5, 0, 3, 6])
    per_mb = featurize({k: v[:-1, idx].flatten(0, 1) for k, v in roll["raw"].items()}, scale)
    assert once.keys() == per_mb.keys()
    for k, v in once.items():
        assert torch.equal(v[:, idx].flatten(0, 1), per_mb[k]), k
    # the distance as it was defined: the sum over a (..., M, N, 2) block of |differences|
    fac_xy, per_xy = once["fac_xy"], once["per_xy"]
    assert torch.equal(once["dist"], (fac_xy[..., :, None, :] - per_xy[..., None, :, :]).abs().sum(-1))
    # the dispatch mask as it was defined: requesting x dispatchable, then the always-allowed no-op column
    req, disp = once["requesting"], roll["raw"]["dispatchable"][:-1] > 0
    old = torch.cat([req[..., :, None] & disp[..., None, :], torch.ones_like(req[..., :1])[..., None]
                     .expand(*req.shape, 1)], -1)
    assert torch.equal(once["dispatch_mask"], old)


def test_train_speed__pointer_distance_prior_same_bits_forward_and_backward():
    gen = torch.Generator().manual_seed(0)
    dist = torch.randint(0, 129, (64, 50, 50), generator=gen).float() / 64.0
    upstream = torch.randn(64, 50, 50, generator=gen) * 1e-3
    grads, outs = [], []
    for new in (False, True):
        s = torch.tensor(3.0, requires_grad=True)
        term = (F.softplus(s) * 8.0) * dist if new else F.softplus(s) * dist * 8.0
        (term * upstream).sum().backward()
        outs.append(term.detach())
        grads.append(s.grad.clone())
    assert torch.equal(outs[0], outs[1])
    assert torch.equal(grads[0], grads[1])
