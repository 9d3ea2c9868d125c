"""The IMPALA trainer (issue #14): V-trace against hand-computed numbers, the actor's lag, a run end to end.

- V-trace: on-policy with rho_bar = c_bar = lambda = 1 it is the n-step return bootstrapped
  from V(x_T) (GAE(lambda = 1)'s return), with no bootstrap across an episode's end;
  off-policy the weights are truncated at rho_bar and c_bar (numbers worked by hand);
- the actor acts with parameters that really lag the learner's (sync: exactly
  update mod K; async: within the queue's bound), and the importance weights see it;
- a tiny run: finite losses, checkpoints, resume, best.pt on public seeds, the checkpoint
  scored through ``wfbench.evaluate`` as ``ppo:PATH``; the same seed gives the same weights;
- bad settings: one clear ValueError each.
"""

import json

import numpy as np
import pytest
import torch

import wfbench
from wfbench import policies
from wfbench.train.impala import ImpalaConfig, Trainer, vtrace


def _col(*xs):
    """(T,) numbers -> a (T, 1) tensor: one environment."""
    return torch.tensor(xs, dtype=torch.float64)[:, None]


# -- V-trace ------------------------------------------------------------------------------------
def test_impala__vtrace_on_policy_is_the_n_step_return_by_hand():
    r, v, boot, g = _col(1.0, 2.0, 3.0), _col(0.5, 0.4, 0.3), torch.tensor([1.0], dtype=torch.float64), 0.9
    out = vtrace(torch.zeros(3, 1, dtype=torch.float64), r, torch.full((3, 1), g, dtype=torch.float64), v, boot)
    # v_2 = 3 + 0.9 * 1 = 3.9;  v_1 = 2 + 0.9 * 3.9 = 5.51;  v_0 = 1 + 0.9 * 5.51 = 5.959
    assert out.vs[:, 0].tolist() == pytest.approx([5.959, 5.51, 3.9])
    # A_t = r_t + gamma v_{t+1} - V(x_t): 1 + 4.959 - 0.5, 2 + 3.51 - 0.4, 3 + 0.9 - 0.3
    assert out.pg_adv[:, 0].tolist() == pytest.approx([5.459, 5.11, 3.6])
    # the episode ends after step 1: no bootstrap across it
    disc = _col(g, 0.0, g)
    out = vtrace(torch.zeros(3, 1, dtype=torch.float64), r, disc, v, boot)
    assert out.vs[:, 0].tolist() == pytest.approx([1 + 0.9 * 2, 2.0, 3.9])


def test_impala__vtrace_on_policy_equals_gae_lambda_1_returns():
    gen = torch.Generator().manual_seed(0)
    T, B, g = 12, 5, 0.97
    r = torch.randn(T, B, generator=gen, dtype=torch.float64)
    v = torch.randn(T, B, generator=gen, dtype=torch.float64)
    boot = torch.randn(B, generator=gen, dtype=torch.float64)
    done = (torch.rand(T, B, generator=gen) < 0.2).double()
    out = vtrace(torch.zeros(T, B, dtype=torch.float64), r, g * (1 - done), v, boot)
    # GAE(lambda = 1) written as ppo.py does, independently of vtrace()
    adv, last = torch.zeros(T, B, dtype=torch.float64), torch.zeros(B, dtype=torch.float64)
    for t in reversed(range(T)):
        nv = boot if t == T - 1 else v[t + 1]
        delta = r[t] + g * nv * (1 - done[t]) - v[t]
        last = delta + g * (1 - done[t]) * last
        adv[t] = last
    torch.testing.assert_close(out.vs, adv + v)
    torch.testing.assert_close(out.pg_adv, adv)  # on-policy, lambda 1: A_t = r_t + gamma v_{t+1} - V = GAE(1)
    assert torch.all(out.rhos == 1)


def test_impala__vtrace_truncation_by_hand():
    r, v, boot, g = _col(1.0, 2.0), _col(0.5, 0.4), torch.tensor([1.0], dtype=torch.float64), 0.9
    log_rhos = torch.log(_col(0.5, 3.0))  # pi / mu = 0.5, then 3.0
    disc = torch.full((2, 1), g, dtype=torch.float64)
    out = vtrace(log_rhos, r, disc, v, boot, rho_bar=1.0, c_bar=1.0)
    # rho = c = (0.5, 1): delta_1 = 2 + 0.9 - 0.4 = 2.5, v_1 = 2.9;
    # delta_0 = 0.5 (1 + 0.36 - 0.5) = 0.43, v_0 = 0.5 + 0.43 + 0.9 * 0.5 * 2.5 = 2.055
    assert out.rhos[:, 0].tolist() == pytest.approx([0.5, 1.0])
    assert out.vs[:, 0].tolist() == pytest.approx([2.055, 2.9])
    # A_0 = 0.5 (1 + 0.9 * 2.9 - 0.5) = 1.555, A_1 = 2.5
    assert out.pg_adv[:, 0].tolist() == pytest.approx([1.555, 2.5])
    # rho_bar = c_bar = 0.8: rho = c = (0.5, 0.8): delta_1 = 0.8 * 2.5 = 2, v_1 = 2.4;
    # v_0 = 0.5 + 0.43 + 0.45 * 2 = 1.83; A_0 = 0.5 (0.5 + 0.9 * 2.4) = 1.33, A_1 = 2
    out = vtrace(log_rhos, r, disc, v, boot, rho_bar=0.8, c_bar=0.8)
    assert out.rhos[:, 0].tolist() == pytest.approx([0.5, 0.8])
    assert out.vs[:, 0].tolist() == pytest.approx([1.83, 2.4])
    assert out.pg_adv[:, 0].tolist() == pytest.approx([1.33, 2.0])
    # c_bar alone: c = (0.5, 0.3) changes nothing here (c_1 multiplies v_2 - V(x_2) = 0), c_0 does:
    # rho_bar 1, c_bar 0.3: c_0 = 0.3; v_0 = 0.5 + 0.43 + 0.9 * 0.3 * 2.5 = 1.605
    out = vtrace(log_rhos, r, disc, v, boot, rho_bar=1.0, c_bar=0.3)
    assert out.vs[:, 0].tolist() == pytest.approx([1.605, 2.9])


# -- training -----------------------------------------------------------------------------------
def _cfg(tmp_path, **kw):
    base = dict(scenario="small", model="tiny", num_envs=4, num_steps=8, steps=4 * 8 * 2, eval_every=0,
                checkpoint_every=1, run_dir=str(tmp_path / "run"), seed=3, mode="sync")
    return ImpalaConfig(**{**base, **kw})


@pytest.mark.slow
def test_impala__actor_parameters_lag_the_learner(tmp_path):
    tr = Trainer(_cfg(tmp_path, sync_every=3, steps=10**6, lr=3e-3), progress=False, log=False)
    stats, versions = [], []
    for _ in range(6):
        stats.append(tr.train(updates=1))
        versions.append(tr.actor.version)  # the learner update whose parameters made the last rollout
        actor, learner = tr.actor.model.state_dict(), tr.model.state_dict()
        assert not all(torch.equal(actor[k], learner[k]) for k in learner)  # the learner has moved on
    assert versions == [0, 0, 0, 3, 3, 3]  # refreshed every K = 3 updates, not before
    assert tr.lags == [0, 1, 2, 0, 1, 2]
    assert [s["policy_lag"] for s in stats] == [0, 1, 2, 0, 1, 2]
    # the importance weights see the lag: pi = mu (up to float rounding) only at lag 0
    for s in stats:
        if s["policy_lag"] == 0:
            assert s["abs_log_rho"] < 1e-4, s
        else:
            assert s["abs_log_rho"] > 1e-3, s

    # async: an actor thread a rollout ahead through a bounded queue; the lag is real and bounded
    tr = Trainer(_cfg(tmp_path / "a", mode="async", sync_every=2, queue_size=1, steps=4 * 8 * 6), progress=False,
                 log=False)
    tr.train()
    assert len(tr.lags) == 6 and max(tr.lags) >= 1 and max(tr.lags) <= 1 + 2, tr.lags  # queue_size + K
    assert not tr.__dict__.get("_thread"), "the actor thread was not stopped"


@pytest.mark.slow
def test_impala__sync_training_is_deterministic_on_cpu(tmp_path):
    weights = []
    for i in range(2):
        tr = Trainer(_cfg(tmp_path / str(i), sync_every=2), progress=False, log=False)
        stats = tr.train()
        assert all(np.isfinite(v) for v in stats.values()), stats
        weights.append({k: v.clone() for k, v in tr.model.state_dict().items()})
    for k in weights[0]:
        assert torch.equal(weights[0][k], weights[1][k]), k
    tr = Trainer(_cfg(tmp_path / "2", seed=4, sync_every=2), progress=False, log=False)
    tr.train()
    assert any(not torch.equal(weights[0][k], v) for k, v in tr.model.state_dict().items())


@pytest.mark.slow
def test_impala__train_resume_evaluate_end_to_end(tmp_path):
    run = tmp_path / "run"
    cfg = _cfg(tmp_path, eval_every=2, eval_seeds="public:2", optimizer="rmsprop", rho_bar=2.0, c_bar=0.9)
    tr = Trainer(cfg, progress=False, log=True)
    stats = tr.train()
    assert all(np.isfinite(v) for v in stats.values()), stats
    for k in ("pg_loss", "v_loss", "entropy", "policy_lag", "rho_mean"):
        assert k in stats
    assert (run / "latest.pt").is_file() and (run / "best.pt").is_file()
    assert (run / "checkpoints" / "update_000002.pt").is_file()
    assert list((run / "tb").iterdir()), "no TensorBoard log"
    saved = json.loads((run / "config.json").read_text())
    assert saved["algo"] == "impala" and saved["optimizer"] == "rmsprop" and saved["rho_bar"] == 2.0
    best = torch.load(run / "best.pt", weights_only=False)
    assert best["best"]["seeds"] == [1000, 1001] and best["best"]["update"] == 2 and best["algo"] == "impala"
    assert "optimizer" not in best  # a policy, not a resume point
    latest = torch.load(run / "latest.pt", weights_only=False)
    assert latest["update"] == 2 and latest["global_step"] == 64 and latest["seed_cursor"] > 0

    # resume: the settings of the checkpoint, more steps; continues from update 2
    more = ImpalaConfig.from_dict({**latest["train_config"], "steps": 96})
    tr2 = Trainer(more, resume=run / "latest.pt", progress=False, log=False)
    assert tr2.update == 2 and tr2.actor.seed_cursor == latest["seed_cursor"]
    tr2.train()
    resumed = torch.load(run / "latest.pt", weights_only=False)
    assert resumed["update"] == 3 and resumed["global_step"] == 96 and len(resumed["lags"]) == 3
    assert any(not torch.equal(latest["model"][k], resumed["model"][k]) for k in latest["model"])
    with pytest.raises(ValueError, match="no optimizer state"):
        Trainer(more, resume=run / "best.pt", progress=False, log=False)

    # the checkpoint is a policy (the PPO checkpoint format), sampled by default and greedy on request
    for spec in (f"ppo:{run / 'best.pt'}", f"ppo:{run / 'latest.pt'}@greedy"):
        df = wfbench.evaluate(spec, "small", seeds=[0, 1])
        assert df["nsw"].between(0, 1).all() and (df["invalid_actions"] == 0).all()
    assert policies.get(f"ppo:{run / 'best.pt'}").mode == "sample"


def test_impala__ctrl_c_saves_and_stops_the_actor(tmp_path, monkeypatch):
    tr = Trainer(_cfg(tmp_path, mode="async", steps=4 * 8 * 20, checkpoint_every=100), progress=False, log=False)
    learn = tr.learn

    def interrupted(roll):
        if tr.update == 2:
            raise KeyboardInterrupt
        return learn(roll)

    monkeypatch.setattr(tr, "learn", interrupted)
    with pytest.raises(KeyboardInterrupt):
        tr.train()
    assert torch.load(tmp_path / "run" / "latest.pt", weights_only=False)["update"] == 2
    assert not tr.__dict__.get("_thread")


@pytest.mark.parametrize("kw, message", [
    (dict(mode="ray"), "mode 'ray' is not allowed; allowed: async, sync"),
    (dict(optimizer="sgd"), "optimizer 'sgd' is not allowed; allowed: adam, rmsprop"),
    (dict(variant="dispatch"), "variant 'dispatch' is not allowed for impala; allowed: joint"),
    (dict(rho_bar=0.0), r"rho_bar = 0.0 is not allowed; allowed: a number > 0"),
    (dict(c_bar=2.0), r"c_bar = 2.0 > rho_bar = 1.0 is not allowed; allowed: c_bar <= rho_bar"),
    (dict(gamma=1.5), r"gamma = 1.5 is not allowed; allowed: a number in \(0, 1\]"),
    (dict(vtrace_lambda=0.0), r"vtrace_lambda = 0.0 is not allowed; allowed: a number in \(0, 1\]"),
    (dict(sync_every=0), "sync_every = 0 is not allowed; allowed: an integer >= 1"),
    (dict(queue_size=0), "queue_size = 0 is not allowed; allowed: an integer >= 1"),
    (dict(eval_seeds="test:5"), "public seeds"),
    (dict(model="huge"), "unknown model preset 'huge'"),
])
def test_impala__bad_config_is_refused_clearly(tmp_path, kw, message):
    with pytest.raises(ValueError, match=message):
        _cfg(tmp_path, **kw).validate()
