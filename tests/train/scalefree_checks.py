"""Checks that any trainer's scale-free run passes (issue #44): used by the IMPALA and hindsight tests."""

import torch
from wfbench.policies.neural import scalefree

import wfbench
from wfbench import policies


def assert_trained_and_plays(a, b, algo: str, tmp_path) -> None:
    """``a`` moved from its seeded start, ``b`` (the same run again) is bit-identical, and ``a``'s checkpoint
    reads observation version 2 and plays an episode through ``wfbench.evaluate`` as ``ALGO:PATH``."""
    torch.manual_seed(a.run.config.seed)
    fresh = scalefree.ScaleFreeNet(a.run.network).state_dict()  # the run's initial parameters (seeded as start_run)
    assert any(not torch.equal(p, fresh[n]) for n, p in a.model.state_dict().items()), "the parameters did not move"
    for (n, p), q in zip(a.model.state_dict().items(), b.model.state_dict().values(), strict=True):
        assert torch.equal(p, q), n

    path = a.save(tmp_path / "a.pt", full=False)
    ckpt = torch.load(path, weights_only=False)
    assert ckpt["algo"] == algo and ckpt["obs_version"] == 2 and ckpt["model_config"]["arch"] == "scalefree"
    pol = policies.get(f"{algo}:{path}")
    assert scalefree.obs_version(pol.model) == 2 and pol.observation_version == 2
    df = wfbench.evaluate(f"{algo}:{path}", "small", seeds=[1000])
    assert len(df) == 1 and df["nsw"].between(0, 1).all() and (df["invalid_actions"] == 0).all()
