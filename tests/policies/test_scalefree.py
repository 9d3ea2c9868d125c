"""The scale-free network (wfbench.policies.neural.scalefree): its actions, distributions, training and checkpoints."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from wfbench.policies.neural import scalefree  # noqa: E402
from wfbench.policies.neural.policy import from_checkpoint  # noqa: E402

import wfbench  # noqa: E402
from wfbench import policies  # noqa: E402
from wfbench.core.observation_v2 import observe_v2, scaled_world  # noqa: E402
from wfbench.core.simulator import Simulator  # noqa: E402


def busy_batch(scenario="paper-64", seeds=(3, 4, 5, 6), steps=60):
    """An observation of a few environments run a while by the heuristic, many requests open."""
    sim = Simulator(wfbench.scenario(scenario), list(seeds), keep_series=False, threads=1)
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset(list(seeds))
    for t in range(steps):
        act = pol.act(obs)
        if t % 3:  # let requests pile up: some steps dispatch nobody
            act["dispatch"] = np.full_like(act["dispatch"], sim.N)
        obs = sim.step_observe(act)[1]
    return sim, {k: np.array(v, copy=True) for k, v in obs.items()}


def forward(net, obs):
    x = net.featurize(scalefree.obs_to_torch(observe_v2(obs)))
    B = obs["requesting"].shape[0]
    out, _ = net(x, net.initial_state(B), torch.ones(1, B))
    return x, out


@pytest.fixture(scope="module")
def net():
    torch.manual_seed(0)
    return scalefree.ScaleFreeNet(scalefree.scalefree_config()).eval()


def test_sampled_dispatch_is_valid_and_among_the_k_nearest(net):
    sim, obs = busy_batch()
    x, out = forward(net, obs)
    assert int(x["choose"].sum()) >= 4, "the batch should have facilities that choose"
    gen = torch.Generator().manual_seed(1)
    shapes = net.noise_shapes(sim.B, sim.M, sim.N)
    noise = {k: -torch.log(-torch.log(torch.rand(s, generator=gen).clamp(1e-10, 1 - 1e-7))) for k, s in shapes.items()}
    v2 = observe_v2(obs)
    for n in (None, noise):
        acts = net.sample(out, x, n)["dispatch"].numpy()
        for b in range(sim.B):
            sent = acts[b][acts[b] < sim.N]
            assert len(sent) == len(set(sent.tolist())), "nobody is sent twice"
            for f in np.flatnonzero(acts[b] < sim.N):
                p = acts[b, f]
                assert obs["requesting"][b, f] and obs["dispatchable"][b, p]
                free = np.flatnonzero(obs["dispatchable"][b])
                tt = np.abs(v2["facilities"][b, f, :2] - v2["personnel"][b][free][:, 2:4]).sum(-1)
                assert np.sort(tt)[min(net.config.k, len(free)) - 1] >= tt[free.tolist().index(p)] - 1e-5
            # a facility without an open request or without anyone free sends nobody
            assert (acts[b][~x["choose"][b].numpy()] == sim.N).all()


def test_log_prob_is_the_softmax_of_what_the_sampler_allowed(net):
    sim, obs = busy_batch()
    x, out = forward(net, obs)
    acts = net.sample(out, x, None)
    heads = net.log_prob_entropy(out, x, acts)
    lp, ent = heads["dispatch"]
    assert torch.isfinite(lp).all() and (lp <= 0).all() and (ent >= 0).all()
    # the first choosing facility of each environment: nothing is taken before it, so its log-probability is
    # the plain log-softmax of its logits over its valid candidates and the no-op
    rows, facs = x["choose"].nonzero(as_tuple=True)
    logits = out["dispatch"]
    for b in rows.unique().tolist():
        i = int((rows == b).nonzero()[0])
        f = int(facs[i])
        valid = torch.cat([x["cand_valid"][b, f], torch.tensor([True])])
        ref = torch.log_softmax(logits[i].masked_fill(~valid, -1e9), -1)
        p = int(acts["dispatch"][b, f])
        j = net.config.k if p == sim.N else int((x["cand"][b, f] == p).nonzero()[0])
        if int((rows == b).sum()) == 1:  # one choosing facility: the row's whole dispatch log-probability
            torch.testing.assert_close(lp[b], ref[j])
        assert ref[j] <= 0


def test_the_twin_world_gives_the_same_outputs_and_actions(net):
    """Lengths and speed times k: the same features, head outputs and actions (the observation is built by hand)."""
    sim, obs = busy_batch(scenario="small", seeds=(1, 2), steps=40)
    x, out = forward(net, obs)
    for k in (2, 4):
        twin = dict(obs)
        for key, cols in (("facilities", [0, 1]), ("personnel", [0, 1, 2, 3])):
            arr = obs[key].copy()
            arr[..., cols] *= k
            twin[key] = arr
        twin["world"] = Simulator(scaled_world(sim.config, k), [1, 2], keep_series=False).world_key(obs["t"]).copy()
        x2, out2 = forward(net, twin)
        for key in x:
            assert torch.equal(x[key], x2[key]), key
        for key in ("value", "workforce", "dispatch"):
            assert torch.equal(out[key], out2[key]), key
        assert all(torch.equal(a, b) for a, b in zip(net.sample(out, x, None).values(),
                                                      net.sample(out2, x2, None).values(), strict=True))


def test_positioning_runs_only_where_the_workforce_action_uses_it(net, monkeypatch):
    sim, obs = busy_batch(seeds=(1, 2, 3))
    x, out = forward(net, obs)
    seen = []
    real = net.positioning
    monkeypatch.setattr(net, "positioning", lambda o, rows, which: seen.append(rows.clone()) or real(o, rows, which))
    noise = {"workforce": torch.tensor([[0.0, 50.0, 0, 0, 0, 0, 0], [0.0] * 7, [0.0] * 7]),
             "dispatch": torch.zeros(net.noise_shapes(3, sim.M, sim.N)["dispatch"]),
             "positioning": torch.zeros(3, 2, sim.M)}
    acts = net.sample(out, x, noise)
    assert acts["workforce"][0] == 1 and (acts["workforce"][1:] == 0).all()
    assert [r.tolist() for r in seen] == [[0]]
    lp, _ = net.log_prob_entropy(out, x, acts)["positioning"]
    assert lp[1:].eq(0).all() and lp[0] < 0


def _train(tmp_path, name, seed=0):
    from wfbench.train.ppo import TrainConfig, Trainer
    cfg = TrainConfig(scenarios="small,paper-64", model="scalefree", num_envs=4, num_steps=8, steps=64, epochs=1,
                      minibatches=2, eval_every=0, threads=1, seed=seed, run_dir=str(tmp_path / name))
    tr = Trainer(cfg, progress=False, log=False)
    tr.train()
    return tr


@pytest.mark.slow
def test_ppo_trains_it_deterministically_and_the_checkpoint_says_its_observation(tmp_path):
    a, b = _train(tmp_path, "a"), _train(tmp_path, "b")
    for (n, p), q in zip(a.model.state_dict().items(), b.model.state_dict().values(), strict=True):
        assert torch.equal(p, q), n
    assert any(not torch.equal(p, q) for p, q in zip(a.model.state_dict().values(),
                                                      scalefree.ScaleFreeNet(a.run.network).state_dict().values(),
                                                      strict=True))
    path = a.save(tmp_path / "a.pt")
    ckpt = torch.load(path, weights_only=False)
    assert ckpt["obs_version"] == 2 and ckpt["model_config"]["arch"] == "scalefree"
    pol = from_checkpoint(path)
    assert pol.observation_version == 2
    from wfbench.harness.evaluation import evaluate
    df = evaluate(pol, "small", [1000, 1001], act_timeout_s=None)
    assert len(df) == 2 and df["nsw"].between(0, 1).all()


def test_shipped_networks_of_before_read_version_1():
    assert from_checkpoint(wfbench.policies.registry.CHECKPOINT_DIR / "ppo-joint-paper-64.pt").observation_version == 1


@pytest.mark.slow
def test_what_cannot_train_it_says_so_in_one_line(tmp_path):
    # every trainer trains it (issue #44); one network per decision cannot be it
    r = subprocess.run([sys.executable, "-m", "wfbench.cli", "train", "--algo", "ppo", "--agents", "independent",
                        "--model", "scalefree", "--steps", "64", "--run-dir", str(tmp_path / "x")],
                       capture_output=True, text=True)
    assert r.returncode != 0
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "agents 'independent' with model 'scalefree' is not allowed" in lines[0] \
        and "allowed: agents joint" in lines[0]
    assert not (tmp_path / "x").exists()
