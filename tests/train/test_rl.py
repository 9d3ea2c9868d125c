"""The PPO model, its masks and the trainer (issue #13): behaviour, not just that it runs.

- masks: an empty slot, a masked person, a masked workforce code or an inactive facility
  never gets probability, no person is sent twice, and garbage in empty slots changes
  nothing the network outputs for the rest;
- one network runs on two scenario sizes;
- a short training run on CPU: finite losses, checkpoints, resume, a checkpoint scored
  through ``wfbench.evaluate`` and the command line; the same seed gives the same weights.
"""

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from wfbench.policies.neural.dist import gumbel, log_prob_entropy, noise_shapes, sample
from wfbench.policies.neural.model import WorkforceNet, count_parameters, featurize, model_config, obs_to_torch

import wfbench
from wfbench import policies
from wfbench.cli import main as cli_main
from wfbench.train.ppo import TrainConfig, Trainer

ROOT = Path(__file__).resolve().parents[2]


def _mid_episode_obs(scenario, seeds, steps=60):
    """An observation after ``steps`` heuristic steps: open requests, busy people, empty slots."""
    sim = wfbench.Simulator(wfbench.scenario(scenario), seeds)
    obs = sim.reset()
    h = policies.get("heuristic")
    h.reset(seeds)
    for _ in range(steps):
        obs = sim.step_observe(h.act(obs))[1]
    return {k: np.array(v, copy=True) for k, v in obs.items()}


@pytest.fixture(scope="module")
def paper_obs():
    return _mid_episode_obs("paper-64", [0, 1, 2, 3], steps=40)


def _net(decisions=("dispatch", "workforce", "positioning")):
    torch.manual_seed(0)
    return WorkforceNet(model_config("tiny", decisions)).eval()


def _run(net, obs):
    x = featurize(obs_to_torch(obs), net.config.coord_scale)
    B = obs["t"].shape[0]
    with torch.no_grad():
        out, _ = net(x, net.initial_state(B), torch.ones(1, B))
    return x, out


def test_rl__masked_entries_never_get_probability(paper_obs):
    net = _net()
    x, out = _run(net, paper_obs)
    dm = torch.from_numpy(paper_obs["dispatch_mask"] > 0)
    assert torch.equal(x["dispatch_mask"], dm)  # rebuilt from requesting and dispatchable, as documented
    assert (~dm[..., :-1]).any() and dm[..., :-1].any()  # something to mask and something allowed
    gen = torch.Generator().manual_seed(0)
    B, M, N = dm.shape[0], dm.shape[1], dm.shape[2] - 1
    empty_people = paper_obs["personnel_mask"] == 0
    assert empty_people.any(), "the fixture needs empty personnel slots"
    for _ in range(50):
        noise = {k: gumbel(s, gen) * 3 for k, s in noise_shapes(B, M, N).items()}  # hot noise: reach everywhere
        a = sample(out, x, noise)
        d = a["dispatch"].numpy()
        for b in range(B):
            for f in range(M):
                assert paper_obs["dispatch_mask"][b, f, d[b, f]], (b, f, d[b, f])
            sent = d[b][d[b] < N]
            assert len(sent) == len(set(sent)), "a person was sent to two facilities"
            assert not empty_people[b, sent].any()
        assert paper_obs["workforce_mask"][np.arange(B), a["workforce"].numpy()].all()
        pos = a["positioning"].numpy()
        assert (paper_obs["facility_mask"][np.arange(B)[:, None], pos] > 0).all()
        logp, ent, _ = log_prob_entropy(out, x, a)
        assert torch.isfinite(logp).all() and torch.isfinite(ent).all() and (logp <= 1e-6).all()
    # the probabilities themselves: zero outside the masks
    wf = torch.softmax(out["workforce"].masked_fill(~x["workforce_mask"], -1e9), -1)
    assert (wf[~x["workforce_mask"]] == 0).all()
    disp = torch.softmax(out["dispatch"].masked_fill(~x["dispatch_mask"], -1e9), -1)
    assert (disp[~x["dispatch_mask"]] == 0).all()


def _dispatch_logp_ent_by_loop(logits, mask, act):
    """The definition, one facility at a time: slot order, people picked earlier are masked, no-op allowed."""
    B, M, N1 = logits.shape
    logp, ent = torch.zeros(B, dtype=torch.float64), torch.zeros(B, dtype=torch.float64)
    for b in range(B):
        taken = set()
        for f in range(M):
            if not mask[b, f, :-1].any():
                continue  # no real choice: the no-op with probability 1
            allowed = mask[b, f].clone()
            allowed[list(taken)] = False
            allowed[-1] = True
            lp = torch.log_softmax(logits[b, f].double().masked_fill(~allowed, -1e9), -1)
            logp[b] += lp[act[b, f]]
            ent[b] -= (lp.exp() * lp.masked_fill(~allowed, 0.0)).sum()
            if act[b, f] < N1 - 1:
                taken.add(int(act[b, f]))
    return logp, ent


def test_rl__dispatch_log_prob_matches_its_definition(paper_obs):
    """The sparse log-probability (choosing facilities only) equals the facility-by-facility definition."""
    net = _net(("dispatch",))
    x, out = _run(net, paper_obs)
    gen = torch.Generator().manual_seed(1)
    B, M, N1 = out["dispatch"].shape
    for scale in (0.0, 1.0, 5.0):  # greedy, then hotter and hotter noise: people taken by earlier facilities
        noise = {k: gumbel(s, gen) * scale for k, s in noise_shapes(B, M, N1 - 1).items()}
        a = sample(out, x, noise)
        logp, ent, parts = log_prob_entropy(out, x, a)
        ref_logp, ref_ent = _dispatch_logp_ent_by_loop(out["dispatch"], x["dispatch_mask"], a["dispatch"])
        torch.testing.assert_close(logp.double(), ref_logp, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(parts["dispatch"].double(), ref_ent, rtol=1e-5, atol=1e-5)
        assert (ref_logp < 0).any()  # some facilities had a real choice
    # no facility with a choice at all: zero, not an error
    none = {**x, "dispatch_mask": x["dispatch_mask"] & False}
    logp, ent, _ = log_prob_entropy(out, none, a)
    assert (logp == 0).all() and (ent == 0).all()


def test_rl__garbage_in_empty_slots_changes_nothing(paper_obs):
    net = _net()
    _, out = _run(net, paper_obs)
    dirty = {k: v.copy() for k, v in paper_obs.items()}
    rng = np.random.default_rng(0)
    empty = dirty["personnel_mask"] == 0
    dirty["personnel"][empty] = rng.uniform(0, 60, size=(empty.sum(), dirty["personnel"].shape[-1])).round()
    dirty["personnel_status"][empty] = 2
    _, out2 = _run(net, dirty)
    torch.testing.assert_close(out["value"], out2["value"], rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(out["workforce"], out2["workforce"], rtol=1e-5, atol=1e-5)
    active = torch.from_numpy(paper_obs["personnel_mask"] > 0)
    for b in range(active.shape[0]):
        cols = torch.cat([active[b], torch.tensor([True])])
        torch.testing.assert_close(out["dispatch"][b][:, cols], out2["dispatch"][b][:, cols], rtol=1e-5, atol=1e-5)


def test_rl__one_network_two_scenario_sizes(paper_obs):
    net = _net()
    small = _mid_episode_obs("small", [0, 1, 2], steps=10)
    for obs in (small, paper_obs):
        B, M = obs["requesting"].shape
        N = obs["personnel"].shape[1]
        x, out = _run(net, obs)
        assert out["dispatch"].shape == (B, M, N + 1)
        assert out["workforce"].shape == (B, 7)
        assert out["positioning"].shape == (B, 2, M)
        assert out["value"].shape == (B,) and out["value"].dtype == torch.float32
    assert small["requesting"].shape[1] != paper_obs["requesting"].shape[1]


def test_rl__presets_sizes():
    assert count_parameters(WorkforceNet(model_config("small"))) < 150_000
    cpu = WorkforceNet(model_config("cpu"))
    assert len(cpu.blocks) == 0 and len(cpu.fusion_fac) == 0  # the CPU preset has no attention
    assert count_parameters(cpu) < count_parameters(WorkforceNet(model_config("small")))
    assert 350_000 <= count_parameters(WorkforceNet(model_config("paper"))) <= 600_000
    with pytest.raises(ValueError, match="unknown model preset"):
        model_config("huge")


def _cfg(tmp_path, **kw):
    base = dict(scenario="small", model="tiny", num_envs=4, num_steps=8, steps=4 * 8 * 2, epochs=1, minibatches=2,
                eval_every=0, checkpoint_every=1, run_dir=str(tmp_path / "run"), seed=3)
    return TrainConfig(**{**base, **kw})


@pytest.mark.slow
def test_rl__training_is_deterministic_on_cpu(tmp_path):
    weights = []
    for i in range(2):
        tr = Trainer(_cfg(tmp_path / str(i)), progress=False, log=False)
        stats = tr.train()
        assert all(np.isfinite(v) for v in stats.values()), stats
        weights.append({k: v.clone() for k, v in tr.model.state_dict().items()})
    for k in weights[0]:
        assert torch.equal(weights[0][k], weights[1][k]), k
    tr = Trainer(_cfg(tmp_path / "2", seed=4), progress=False, log=False)
    tr.train()
    assert any(not torch.equal(weights[0][k], v) for k, v in tr.model.state_dict().items())


@pytest.mark.slow
def test_rl__train_resume_evaluate_end_to_end(tmp_path, capsys):
    run = tmp_path / "run"
    args = ["train", "--scenario", "small", "--model", "tiny", "--num-envs", "4", "--num-steps", "8", "--steps", "64",
            "--epochs", "1", "--eval-every", "2", "--eval-seeds", "public:2", "--checkpoint-every", "1",
            "--run-dir", str(run), "--no-progress", "--seed", "5"]
    assert cli_main(args) == 0
    assert (run / "latest.pt").is_file() and (run / "best.pt").is_file() and (run / "config.json").is_file()
    assert list((run / "tb").iterdir()), "no TensorBoard log"
    best = torch.load(run / "best.pt", weights_only=False)
    assert best["best"]["seeds"] == [1000, 1001] and best["best"]["update"] == 2
    assert "optimizer" not in best  # a policy, not a resume point
    latest = torch.load(run / "latest.pt", weights_only=False)
    assert latest["update"] == 2 and latest["global_step"] == 64
    # resume: continues from update 2, keeps the settings
    assert cli_main(["train", "--resume", str(run / "latest.pt"), "--steps", "96", "--no-progress"]) == 0
    resumed = torch.load(run / "latest.pt", weights_only=False)
    assert resumed["update"] == 3 and resumed["global_step"] == 96
    assert any(not torch.equal(latest["model"][k], resumed["model"][k]) for k in latest["model"])
    # the checkpoint is a policy, sampled by default and greedy on request
    for spec in (f"ppo:{run / 'best.pt'}", f"ppo:{run / 'latest.pt'}@greedy"):
        df = wfbench.evaluate(spec, "small", seeds=[0, 1])
        assert df["nsw"].between(0, 1).all() and (df["invalid_actions"] == 0).all()
    sampled = policies.get(f"ppo:{run / 'best.pt'}")
    assert sampled.mode == "sample" and policies.get(f"ppo:{run / 'best.pt'}@greedy").mode == "greedy"
    capsys.readouterr()
    # user mistakes: one line, exit 2
    assert cli_main(["train", "--resume", str(run / "best.pt"), "--no-progress"]) == 2
    assert "no optimizer state" in capsys.readouterr().err
    assert cli_main(["train", "--eval-seeds", "test:5", "--run-dir", str(tmp_path / "x"), "--no-progress"]) == 2
    assert "public seeds" in capsys.readouterr().err
    assert cli_main(["train", "--gamma", "1.5", "--run-dir", str(tmp_path / "x"), "--no-progress"]) == 2
    assert "gamma = 1.5 is not allowed; allowed: a number in (0, 1]" in capsys.readouterr().err
    assert cli_main(["evaluate", "--policy", f"ppo:{tmp_path / 'nope.pt'}", "--seeds", "1"]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.slow
def test_rl__a_run_without_evaluation_writes_its_last_weights_as_best_pt(tmp_path, capsys):
    """``--eval-every 0``: best.pt exists (the README evaluates it), holds the last weights, says it was not chosen."""
    run = tmp_path / "run"
    assert cli_main(["train", "--scenario", "small", "--model", "tiny", "--num-envs", "4", "--num-steps", "8",
                     "--steps", "64", "--epochs", "1", "--eval-every", "0", "--run-dir", str(run), "--no-progress",
                     "--no-tensorboard", "--seed", "5"]) == 0
    out = capsys.readouterr().out
    assert "best.pt: the last weights, not selected (no evaluation on the public seeds ran: --eval-every 0)" in out
    best, latest = (torch.load(run / f, weights_only=False) for f in ("best.pt", "latest.pt"))
    assert best["best"]["selected"] is False and best["best"]["score"] is None and best["best"]["update"] == 2
    assert latest["best"]["update"] is None, "the trainer's own best stays unset: a resume with evaluation replaces it"
    assert best["model"].keys() == latest["model"].keys()
    assert all(torch.equal(best["model"][k], latest["model"][k]) for k in latest["model"])
    assert "optimizer" not in best  # a policy, not a resume point
    df = wfbench.evaluate(f"ppo:{run / 'best.pt'}", "small", seeds=[0])
    assert df["nsw"].between(0, 1).all()


def test_rl__a_network_on_another_scenario_is_named_once_with_both_scenarios():
    """A shipped paper-64 network knows its scenario; on ``small`` the check warns naming both, on paper-64 not."""
    from wfbench.policies.registry import ScenarioMismatchWarning, warn_if_trained_elsewhere

    for name in ("ppo-joint", "ppo-dispatch"):  # a network alone, and one inside a composite with the heuristics
        policy = policies.get(name)
        assert policy.trained_on == "paper-64"
        with pytest.warns(ScenarioMismatchWarning) as caught:
            assert warn_if_trained_elsewhere(policy, "small")
        assert len(caught) == 1
        assert str(caught[0].message).startswith(f"policy '{name}' was trained on scenario 'paper-64' and is "
                                                 "evaluated on 'small'")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert not warn_if_trained_elsewhere(policy, "paper-64")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not warn_if_trained_elsewhere(policies.get("heuristic"), "small")  # not trained: no scenario


@pytest.mark.slow
def test_rl__independent_agents_train_as_one_network_per_decision(tmp_path, capsys):
    from wfbench.policies.neural.model import AgentSet

    tr = Trainer(_cfg(tmp_path, agents="independent", steps=32), progress=False, log=False)
    assert isinstance(tr.model, AgentSet) and list(tr.model.members) == ["dispatch", "workforce", "positioning"]
    for d, net in tr.model.members.items():  # each network has its own head alone, and its own critic
        assert net.config.decisions == (d,)
        assert [hasattr(net, h) for h in ("ptr_q", "wf_head", "pos_head")] == [d == x for x in tr.model.members]
    ids = [{id(p) for p in m.parameters()} for m in tr.model.members.values()]
    assert not (ids[0] & ids[1] or ids[0] & ids[2] or ids[1] & ids[2])  # no shared parameter
    before = {k: v.clone() for k, v in tr.model.state_dict().items()}
    roll = tr.rollout()
    assert roll["value"].shape == (8, 4, 3) and roll["logp"].shape == (8, 4, 3) and roll["adv"].shape == (8, 4, 3)
    # one shared reward, three critics: the advantages differ per agent
    assert not torch.equal(roll["adv"][..., 0], roll["adv"][..., 1])
    tr.learn(roll)
    for d in tr.model.members:
        assert any(not torch.equal(v, before[k]) for k, v in tr.model.state_dict().items()
                   if k.startswith(f"members.{d}.")), f"agent {d} did not learn"
    tr.save(tmp_path / "set.pt")
    pol = policies.get(f"ppo:{tmp_path / 'set.pt'}")  # a trained set is a policy like any other
    df = wfbench.evaluate(pol, "small", seeds=[0, 1])
    assert df["nsw"].between(0, 1).all() and (df["invalid_actions"] == 0).all()
    with pytest.raises(ValueError, match="agents 'independent' needs variant 'joint'"):
        _cfg(tmp_path, agents="independent", variant="dispatch").validate()
    assert cli_main(["train", "--algo", "impala", "--agents", "independent", "--run-dir", str(tmp_path / "x"),
                     "--no-progress"]) == 2
    assert "--agents does not apply to --algo impala" in capsys.readouterr().err


@pytest.mark.slow
def test_rl__dispatch_variant_deploys_with_the_heuristics(tmp_path):
    tr = Trainer(_cfg(tmp_path, variant="dispatch", steps=32), progress=False, log=False)
    tr.train()
    assert set(tr.model.config.decisions) == {"dispatch"} and not hasattr(tr.model, "wf_head")
    pol = policies.get(f"ppo:{tmp_path / 'run' / 'latest.pt'}")
    assert isinstance(pol, policies.Composite)
    assert [getattr(p, "name", "") for p in pol.parts.values()][1:] == ["threshold", "spatial"]
    df = wfbench.evaluate(pol, "small", seeds=[0])
    assert df["nsw"].between(0, 1).all()


def test_rl__importing_wfbench_and_policies_does_not_import_torch():
    code = "import sys, wfbench, policies, wfbench.cli; policies.names(); assert 'torch' not in sys.modules"
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr


@pytest.mark.slow
def test_rl__episodes_are_staggered_by_partial_reset(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=20), progress=False, log=False)  # small: horizon 200, B = 4
    assert list(tr.env.cut) == [50, 100, 150, 200]
    seeds0 = tr.sim.seeds.copy()
    dones = []
    for _ in range(8):  # 160 steps: envs 0, 1, 2 cut at 50, 100, 150
        roll = tr.rollout()
        dones.append(roll["done"])
    t = tr.sim.state.t
    assert t.tolist() == [110, 60, 10, 160]  # the environments are at different steps of their episodes
    done = torch.cat(dones).numpy()
    assert done[:, 0].sum() == 1 and done[:, 3].sum() == 0  # env 0 cut at step 50, env 3 still in its first
    assert np.flatnonzero(done[:, 0])[0] == 49 and tr.sim.seeds[0] not in seeds0  # onto a fresh train seed
    assert tr.sim.seeds[0] >= 1_000_000
    sync = Trainer(_cfg(tmp_path / "s", stagger=False), progress=False, log=False)
    assert list(sync.env.cut) == [200] * 4


@pytest.mark.slow
def test_rl__init_starts_from_a_checkpoints_weights(tmp_path):
    first = Trainer(_cfg(tmp_path / "a", steps=32), progress=False, log=False)
    first.train()
    ckpt = tmp_path / "a" / "run" / "latest.pt"
    second = Trainer(_cfg(tmp_path / "b", seed=9, init=str(ckpt)), progress=False, log=False)
    for k, v in first.model.state_dict().items():
        assert torch.equal(v, second.model.state_dict()[k]), k
    assert second.update == 0 and second.run.global_step == 0  # a new run, not a resume
    with pytest.raises(ValueError, match="is not this run's"):
        Trainer(_cfg(tmp_path / "c", model="small", init=str(ckpt)), progress=False, log=False)
    # value warm-up: for its first updates only the value head moves, then everything does
    warm = Trainer(_cfg(tmp_path / "d", seed=9, init=str(ckpt), value_warmup=1, steps=64), progress=False, log=False)
    before = {k: v.clone() for k, v in warm.model.state_dict().items()}
    warm.train(updates=1)
    moved = {k for k, v in warm.model.state_dict().items() if not torch.equal(v, before[k])}
    assert moved and all(k.startswith("value_head.") for k in moved), moved
    warm.train(updates=1)
    assert any(not torch.equal(v, before[k]) for k, v in warm.model.state_dict().items()
               if not k.startswith("value_head."))


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["impala", "hindsight"])
def test_rl__train_command_runs_every_algorithm(tmp_path, capsys, algo):
    """`wfbench train --algo X`: the flags that apply, --set for the rest, --resume knows the run's algorithm."""
    run = tmp_path / algo
    extra = (["--set", "rho_bar=0.9", "--set", "c_bar=0.9"] if algo == "impala"
             else ["--set", "iter_steps=32", "--set", "grad_steps=2", "--set", "burn_in=2"])
    args = ["train", "--algo", algo, "--scenario", "small", "--model", "tiny", "--num-envs", "4", "--num-steps", "8",
            "--steps", "64", "--eval-every", "0", "--run-dir", str(run), "--no-progress", "--no-tensorboard", *extra]
    assert cli_main(args) == 0
    assert f"({algo}) in {run}" in capsys.readouterr().out
    saved = torch.load(run / "latest.pt", weights_only=False)
    assert saved["algo"] == algo and saved["train_config"]["model"] == "tiny"
    if algo == "impala":
        assert saved["train_config"]["rho_bar"] == 0.9
    df = wfbench.evaluate(f"ppo:{run / 'latest.pt'}", "small", [1000])
    assert df["nsw"].between(0, 1).all()
    # resume without --algo: the checkpoint says which trainer; a different --algo is refused
    assert cli_main(["train", "--resume", str(run / "latest.pt"), "--steps", "96", "--no-progress",
                     "--no-tensorboard"]) == 0
    other = "ppo" if algo != "ppo" else "impala"
    assert cli_main(["train", "--algo", other, "--resume", str(run / "latest.pt"), "--no-progress"]) == 2
    assert f"is a {algo} run, not --algo {other}" in capsys.readouterr().err
    # a flag of another algorithm, an unknown or badly typed --set: one line, exit 2
    assert cli_main(["train", "--algo", algo, "--epochs", "3", "--run-dir", str(tmp_path / "x")]) == 2
    assert f"--epochs does not apply to --algo {algo}" in capsys.readouterr().err
    assert cli_main(["train", "--algo", algo, "--set", "nope=1", "--run-dir", str(tmp_path / "x")]) == 2
    assert "expected KEY=VALUE with KEY one of" in capsys.readouterr().err
    assert cli_main(["train", "--algo", algo, "--set", "seed=abc", "--run-dir", str(tmp_path / "x")]) == 2
    assert "seed takes a int value" in capsys.readouterr().err


@pytest.mark.slow
def test_rl__shipped_networks_are_policies_and_reproduce_their_selection_score(capsys):
    """Every shipped checkpoint is listed and loads; ppo-joint scores what it recorded on its public selection seeds."""
    from wfbench.policies.registry import checkpoint_file, learned_names, names_of

    assert set(learned_names()) == set(names_of("learned")), "a registered network has no shipped file"
    assert cli_main(["policies"]) == 0
    listed = capsys.readouterr().out
    for name in names_of("learned"):
        assert name in listed
        pol = policies.get(name)
        assert pol.name == name
    best = torch.load(checkpoint_file("ppo-joint"), weights_only=False)["best"]
    assert set(best["seeds"]) <= set(range(1000, 1050)), "selected on public seeds only"
    df = wfbench.evaluate("ppo-joint", "paper-64", best["seeds"])
    assert df["nsw"].mean() == pytest.approx(best["score"], abs=5e-3)
    assert (df["invalid_actions"] == 0).all()
    # hindsight-ppo is ppo-joint with its workforce head trained by hindsight learning, nothing else
    improved = torch.load(checkpoint_file("hindsight-ppo"), weights_only=False)
    base = torch.load(checkpoint_file("ppo-joint"), weights_only=False)["model"]
    changed = {k.split(".")[0] for k, v in improved["model"].items() if not torch.equal(v, base[k])}
    assert changed == {"wf_head"}, changed
    assert improved["algo"] == "hindsight" and improved["train_config"]["value_rollout"] == "learner"
    assert set(improved["best"]["seeds"]) <= set(range(1000, 1050)), "selected on public seeds only"
    df = wfbench.evaluate("hindsight-ppo", "paper-64", improved["best"]["seeds"])
    assert df["nsw"].mean() == pytest.approx(improved["best"]["score"], abs=5e-3)


def _modes_side_by_side(network: str, mixed: str, steps: int = 60):
    """``network`` in modes sample, greedy and ``mixed`` on the same observations of paper-64: each step's actions.

    The three see the same observations (the sampled mode's episode), so their LSTM states stay equal.
    """
    from wfbench.core.simulator import Simulator

    pols = {m: policies.get(f"{network}@{m}") for m in ("sample", "greedy", mixed)}
    seeds = [1000, 1001, 1002, 1003]
    sim = Simulator(wfbench.scenario("paper-64"), seeds)
    obs = sim.reset()
    for p in pols.values():
        p.reset(seeds)
    for _ in range(steps):
        acts = {m: p.act(obs) for m, p in pols.items()}
        yield obs, acts
        _, obs = sim.step_observe(acts["sample"])


def test_rl__greedy_dispatch_mode_is_argmax_dispatch_with_sampled_workforce():
    sent = 0
    for obs, acts in _modes_side_by_side("ppo-joint", "greedy-dispatch"):
        mixed = acts["greedy-dispatch"]
        assert np.array_equal(mixed["dispatch"], acts["greedy"]["dispatch"])
        assert np.array_equal(mixed["workforce"], acts["sample"]["workforce"])  # the same random stream
        assert np.array_equal(mixed["positioning"], acts["sample"]["positioning"])
        sent += int((mixed["dispatch"] < obs["personnel"].shape[1]).sum())
    assert sent > 0, "no dispatch decision was compared"
    with pytest.raises(ValueError, match="allowed: sample, greedy, greedy-dispatch, greedy-workforce"):
        policies.get("ppo-joint@argmax")


def test_rl__greedy_workforce_mode_is_argmax_workforce_with_sampled_dispatch_and_positioning():
    """A mode a distilled network may be deployed in (docs/rl.md, "Distillation"): the same stream as sample."""
    differs = 0
    for _, acts in _modes_side_by_side("scalefree-general", "greedy-workforce"):
        mixed = acts["greedy-workforce"]
        assert np.array_equal(mixed["workforce"], acts["greedy"]["workforce"])
        assert np.array_equal(mixed["dispatch"], acts["sample"]["dispatch"])
        # where to hire or whom to let go follows the workforce action: the same as sample's where both agree
        same = mixed["workforce"] == acts["sample"]["workforce"]
        assert np.array_equal(mixed["positioning"][same], acts["sample"]["positioning"][same])
        differs += int((~same).sum())
    assert differs > 0, "sampled and greedy workforce never differed: the check compared nothing"




@pytest.mark.slow
def test_rl__evaluating_a_network_on_another_scenario_warns_once():
    """Through the evaluator on the process backend (two workers, two chunks) and the command line: one warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        wfbench.evaluate("ppo-joint", "small", seeds=[0, 1], execution=wfbench.Execution(backend="process", workers=2))
    mismatch = [str(w.message) for w in caught if "was trained on scenario" in str(w.message)]
    assert mismatch == ["policy 'ppo-joint' was trained on scenario 'paper-64' and is evaluated on 'small': it runs, "
                        "but what it learned is of another scenario"], mismatch
    out = subprocess.run([sys.executable, "-c", "import sys; from wfbench.cli import main; sys.exit(main())",
                          "evaluate", "--policy", "ppo-joint", "--scenario", "small", "--seeds", "1", "--backend",
                          "serial"], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stderr.count("was trained on scenario 'paper-64' and is evaluated on 'small'") == 1, out.stderr
