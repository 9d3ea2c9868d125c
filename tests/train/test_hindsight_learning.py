"""Hindsight learning (issue #14, ``wfbench/train/hindsight.py``): behaviour, not just that it runs.

- the labels are the oracle's actions in the states the learner visits: a fresh
  ``oracle`` composite's planner, told the actions the mixture really took, is replayed
  on a fresh simulator and must say the same at every step, while the learner's own
  actions (taken at some steps) differ from them;
- with beta = 1 the collection *is* the teacher: its episode scores what
  ``wfbench.evaluate(teacher)`` scores on the same seeds (both teachers);
- the supervised loss falls; the same seed gives the same weights on CPU;
- a checkpoint is a policy (``ppo:PATH``) scored through ``wfbench.evaluate``, resumes,
  and starts a PPO run (``init``);
- hindsight action values: the planner's value of each workforce action is its
  roll-forward score minus the no-op's (the action it takes is their argmax, NaN where
  masked); the values loss moves the head's mass to the best action; with
  ``train_params="heads"`` only the weighted heads change (a PPO network keeps its
  dispatch and its encoder bit for bit);
- the learner's own action values (``value_rollout="learner"``): over one step they are
  the reward of each workforce action taken in a copy of the environment minus the
  no-op's, computed here by hand with ``fork``; longer roll-forwards are deterministic
  given the noise generator, and none of it moves the real episode;
- a bad setting raises a ValueError naming it and what is allowed; test seeds are refused.
"""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import wfbench  # noqa: E402
from wfbench import policies  # noqa: E402
from wfbench.train.hindsight import HindsightConfig, Trainer  # noqa: E402

TINY = dict(scenario="small", model="tiny", device="cpu", num_envs=3, num_steps=16, burn_in=4, iter_steps=48,
            grad_steps=8, batch_seqs=4, eval_every=0, eval_seeds="public:2")


def _cfg(tmp_path, **kw):
    return HindsightConfig(**{**TINY, "run_dir": str(tmp_path / "run"), **kw})


@pytest.mark.slow
def test_labels_are_the_oracles_action_in_the_learners_state(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=40, teacher="oracle"), progress=False, log=False)
    res = tr.collect(beta=0.5, record_actions=True)
    trail = res["trail"]
    assert res["stats"]["invalid_labels"] == 0
    seeds = [int(s) for s in trail[0]["seeds"]]
    assert all(s >= 1_000_000 for s in seeds)  # training seeds only

    oracle = policies.get("oracle-planner")  # the registry's planner composite, built independently of the trainer
    oracle.attach(wfbench.scenario("small"))
    oracle.reset(seeds)
    planner = oracle.parts["dispatch"].planner
    sim = wfbench.Simulator(wfbench.scenario("small"), seeds)
    obs = sim.reset()
    learner_steps_off_label = 0
    for step in trail:
        assert step["t"] == int(obs["t"][0])
        want = planner.act(obs)
        lab = step["label"]
        np.testing.assert_array_equal(lab["dispatch"], want["dispatch"])
        np.testing.assert_array_equal(lab["workforce"], want["workforce"])
        for b in range(len(seeds)):
            active = np.flatnonzero(obs["facility_mask"][b])
            for row in range(2):  # the label is an active facility of largest weight in the oracle's map
                assert lab["positioning"][b, row] in active
                assert want["positioning"][b, row, lab["positioning"][b, row]] == want["positioning"][b, row,
                                                                                                    active].max()
        act = step["action"]
        for b in range(len(seeds)):
            mine = step["learner"]
            src = want if step["use_oracle"][b] else {**mine, "positioning": None}
            np.testing.assert_array_equal(act["dispatch"][b], src["dispatch"][b])
            assert act["workforce"][b] == src["workforce"][b]
            if not step["use_oracle"][b] and (mine["dispatch"][b] != want["dispatch"][b]).any():
                learner_steps_off_label += 1
        planner.record(act)  # the oracle follows the episode the mixture really played
        obs = sim.step_observe(act)[1]
    # the learner did act, and differently from the oracle: the labels were asked off the oracle's own path
    assert learner_steps_off_label >= 3


@pytest.mark.slow
@pytest.mark.parametrize("teacher", ["oracle", "nearest+oracle+oracle"])
def test_pure_teacher_collection_scores_what_the_teacher_scores(tmp_path, teacher):
    tr = Trainer(_cfg(tmp_path, num_envs=2, num_steps=50, teacher=teacher), progress=False, log=False)
    episodes = []
    seeds = None
    while not episodes:
        res = tr.collect(beta=1.0)
        seeds = seeds or [int(s) for s in tr.sim.seeds]
        episodes += res["episodes"]
    # the teacher "oracle" is the planner: the registry's oracle-planner (its "oracle" takes the best of more)
    df = wfbench.evaluate("oracle-planner" if teacher == "oracle" else teacher, "small", seeds)
    assert episodes[0]["nsw"] == pytest.approx(float(df["nsw"].mean()), abs=1e-12)


@pytest.mark.slow
def test_supervised_loss_falls(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=32, grad_steps=60, batch_seqs=6, lr=3e-3), progress=False, log=False)
    for _ in range(2):
        tr.data.add(tr.collect(beta=1.0)["chunk"])
    before = tr.dataset_loss()
    stats = tr.learn()
    after = tr.dataset_loss()
    assert np.isfinite(stats["loss"])
    assert after["loss"] < 0.8 * before["loss"], (before, after)


@pytest.mark.slow
def test_same_seed_same_weights_on_cpu(tmp_path):
    def weights(seed, name):
        tr = Trainer(_cfg(tmp_path, seed=seed, run_dir=str(tmp_path / name)), progress=False, log=False)
        tr.train(iterations=2)
        return tr.model.state_dict()

    a, b, c = weights(0, "a"), weights(0, "b"), weights(1, "c")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


@pytest.mark.slow
def test_checkpoint_is_a_policy_resumes_and_starts_ppo(tmp_path):
    cfg = _cfg(tmp_path, eval_every=1, steps=48)
    tr = Trainer(cfg, progress=False, log=True)
    tr.train()
    run = tmp_path / "run"
    for name in ("best.pt", "latest.pt", "checkpoints/iter_0001.pt", "config.json", "history.jsonl"):
        assert (run / name).is_file(), name
    assert list((run / "tb").iterdir())
    ckpt = torch.load(run / "best.pt", weights_only=False)
    assert ckpt["best"]["seeds"] == [1000, 1001]
    df = wfbench.evaluate(f"ppo:{run / 'best.pt'}", "small", [1000, 1001])
    assert float(df["nsw"].mean()) == pytest.approx(ckpt["best"]["score"], abs=1e-9)
    assert (df["invalid_actions"] == 0).all()

    more = Trainer(HindsightConfig(**{**vars(cfg), "steps": 96}), resume=run / "latest.pt", progress=False,
                   log=False)
    assert more.iteration == 1 and more.run.global_step == 48
    more.train()
    assert more.iteration == 2 and more.run.global_step == 96

    from wfbench.train.ppo import TrainConfig
    from wfbench.train.ppo import Trainer as PPOTrainer

    ppo = PPOTrainer(TrainConfig(scenario="small", model="tiny", device="cpu", num_envs=2, minibatches=1,
                                 init=str(run / "best.pt"), run_dir=str(tmp_path / "ppo")), progress=False, log=False)
    best = torch.load(run / "best.pt", weights_only=False)  # the resumed run may have found a better one
    assert all(torch.equal(v, best["model"][k]) for k, v in ppo.model.state_dict().items())


@pytest.mark.parametrize("change, words", [
    ({"variant": "dispatch"}, ["variant", "allowed: joint"]),
    ({"teacher": "solver"}, ["teacher", "allowed: oracle, nearest+oracle+oracle"]),
    ({"num_steps": 0}, ["num_steps", "allowed: an integer >= 1"]),
    ({"burn_in": 16}, ["burn_in", "allowed"]),
    ({"beta0": 1.5}, ["beta0", "[0, 1]"]),
    ({"rollout_mode": "argmax"}, ["rollout_mode", "sample, greedy"]),
    ({"dispatch_weight": 0.0, "workforce_weight": 0.0, "positioning_weight": 0.0}, ["weights", "at least one"]),
    ({"dataset_steps": 10}, ["dataset_steps", "at least one chunk"]),
    ({"oracle": {"workforce_every": 0}}, ["workforce_every", "allowed"]),
    ({"workforce_target": "q"}, ["workforce_target", "allowed: action, values, improve"]),
    ({"workforce_target": "improve", "improve_temperature": 0.0}, ["improve_temperature", "> 0"]),
    ({"train_params": "trunk"}, ["train_params", "allowed: all, heads"]),
    ({"workforce_target": "improve", "value_rollout": "mc"}, ["value_rollout", "allowed: planner, learner"]),
    ({"value_rollout": "learner"}, ["value_rollout 'learner'", "allowed: workforce_target values or improve"]),
    ({"workforce_target": "improve", "workforce_weight": 0.0}, ["workforce_weight = 0.0", "not used",
                                                                "allowed: workforce_weight > 0"]),
    ({"workforce_target": "improve", "value_horizon": 0}, ["value_horizon", "allowed: an integer >= 1"]),
    ({"workforce_target": "improve", "value_samples": 1.5}, ["value_samples", "allowed: an integer >= 1"]),
    ({"model": "huge"}, ["huge", "allowed"]),
    ({"device": "tpu"}, ["tpu", "allowed"]),
    ({"eval_seeds": "test:5"}, ["public", "never on test seeds"]),
    ({"eval_seeds": "0-4"}, ["public", "never on test seeds"]),
])
def test_bad_config_raises_a_clear_error(tmp_path, change, words):
    with pytest.raises(ValueError) as info:
        Trainer(_cfg(tmp_path, **change), progress=False, log=False)
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_workforce_values_are_the_planners_scores_and_its_choice_their_argmax():
    oracle = policies.get("nearest+oracle+oracle")
    oracle.attach(wfbench.scenario("small"))
    seeds = [1_000_000, 1_000_001, 1_000_002]
    oracle.reset(seeds)
    planner = oracle.parts["workforce"].planner
    sim = wfbench.Simulator(wfbench.scenario("small"), seeds)
    obs = sim.reset()
    scored = acted = 0
    while not sim.done and int(obs["t"][0]) < 120:
        act = oracle.act(obs)
        v = planner.workforce_values
        if int(obs["t"][0]) % planner.workforce_every:
            assert v is None
        else:
            scored += 1
            assert v.shape == obs["workforce_mask"].shape and (v[:, 0] == 0).all()
            assert np.isnan(v[obs["workforce_mask"] == 0]).all()  # a masked action is never scored
            for b in range(len(seeds)):
                best = np.nanmax(v[b])
                # the no-op wins ties; otherwise the first action of the highest value
                want = 0 if best <= 0 else int(np.flatnonzero(v[b] == best)[0])
                assert int(act["workforce"][b]) == want, (b, v[b], act["workforce"][b])
                acted += want != 0
        _, obs = sim.step_observe(act)  # the composite told its planner the joint action already
    assert scored >= 10 and acted >= 1  # it hired or let go at least once, so the argmax was put to work


@pytest.mark.slow
def test_values_loss_moves_mass_to_the_best_allowed_action():
    logits = torch.zeros(2, 7, requires_grad=True)
    mask = torch.ones(2, 7)
    mask[1, 2] = 0  # action 2 masked in row 1: its (large) value must not pull
    values = torch.tensor([[0.0, 1.0, -1.0, 0, 0, 0, 0], [0.0, -0.5, 9.0, 0.5, 0, 0, 0]])
    batch = {"wf_values": values[None], "wf_scored": torch.ones(1, 2, dtype=torch.bool)}
    valid = torch.ones(2)
    loss = Trainer.values_loss(logits, mask, batch, valid).detach()
    allowed = mask > 0
    scale = values[allowed].std()
    p = torch.softmax(torch.zeros(7).masked_fill(~allowed[1], -1e9), -1)
    want = -((values[0] / scale).mean() + (p * values[1] / scale).sum()) / 2
    assert float(loss) == pytest.approx(float(want), rel=1e-5)
    opt = torch.optim.SGD([logits], lr=1.0)
    for _ in range(50):
        opt.zero_grad()
        Trainer.values_loss(logits, mask, batch, valid).backward()
        opt.step()
    probs = torch.softmax(logits.detach().masked_fill(mask == 0, -1e9), -1)
    assert probs[0].argmax() == 1 and probs[1].argmax() == 3 and probs[0, 1] > 0.9
    batch["wf_scored"][:] = False  # no scored step: no loss, no gradient
    assert float(Trainer.values_loss(logits, mask, batch, valid).detach()) == 0.0


@pytest.mark.slow
def test_improve_target_is_the_old_policy_tilted_by_the_values():
    mask = torch.ones(2, 7)
    mask[1, 2] = 0
    old = torch.log_softmax(torch.tensor([[4.0, 0, 0, 0, 0, 0, 0], [4.0, 0, -1e9, 0, 0, 0, 0]]), -1)
    values = torch.tensor([[0.0, 1.0, -1.0, 0, 0, 0, 0], [0.0, -0.5, 9.0, 0.5, 0, 0, 0]])
    batch = {"wf_values": values[None], "wf_scored": torch.ones(1, 2, dtype=torch.bool), "wf_logp_old": old[None]}
    valid = torch.ones(2)
    scale = values[mask > 0].std()
    logits = torch.zeros(2, 7, requires_grad=True)
    opt = torch.optim.Adam([logits], lr=0.1)
    for _ in range(400):  # the cross-entropy is smallest where the policy is the target
        opt.zero_grad()
        Trainer.values_loss(logits, mask, batch, valid, temperature=2.0).backward()
        opt.step()
    probs = torch.softmax(logits.detach().masked_fill(mask == 0, -1e9), -1)
    want = torch.softmax((old + values / scale / 2.0).masked_fill(mask == 0, -1e9), -1)
    assert torch.allclose(probs, want, atol=2e-3), (probs, want)
    assert probs[1, 2] < 1e-6  # the masked action gets nothing, whatever its value
    # a small step: the no-op keeps most of its mass (old 0.9), the better hire gains, the worse loses
    assert probs[0, 0] > 0.8 and probs[0, 1] > torch.exp(old[0, 1]) > probs[0, 2]


def test_heads_only_values_run_keeps_the_networks_other_parts(tmp_path):
    base = Trainer(_cfg(tmp_path, run_dir=str(tmp_path / "base")), progress=False, log=False)
    base.save(tmp_path / "init.pt", full=False)
    init = {k: v.clone() for k, v in base.model.state_dict().items()}
    tr = Trainer(_cfg(tmp_path, init=str(tmp_path / "init.pt"), beta0=0.0, dispatch_weight=0.0,
                      workforce_target="values", train_params="heads", lr=1e-2, oracle={"workforce_every": 2}),
                 progress=False, log=False)
    res = tr.collect(beta=0.0)
    chunk = res["chunk"]
    assert chunk["wf_scored"].shape == chunk["starts"].shape
    assert chunk["wf_scored"][:, 0::2].all() and not chunk["wf_scored"][:, 1::2].any()  # every other step
    tr.data.add(chunk)
    tr.learn()
    after = tr.model.state_dict()
    changed = {k.split(".")[0] for k in after if not torch.equal(after[k], init[k])}
    assert changed == {"wf_head", "pos_head"}, changed


def test_learner_values_are_roll_forwards_in_copies_that_leave_the_episode_alone(tmp_path):
    from wfbench.core.fork import fork, state_equal

    tr = Trainer(_cfg(tmp_path, beta0=0.0, workforce_target="improve", value_rollout="learner", value_horizon=1,
                      value_every=4), progress=False, log=False)
    chunk = tr.collect(beta=0.0)["chunk"]
    assert chunk["wf_scored"][:, 0::4].all() and not chunk["wf_scored"][:, 1::4].any()  # t = 0, 4, 8, 12
    scored = chunk["wf_values"][chunk["wf_scored"]]
    assert (scored[:, 0] == 0).all() and scored.abs().sum() > 0  # relative to the no-op, and not all ties

    sim, B, M, N = tr.sim, tr.sim.B, tr.sim.M, tr.sim.N
    mask = tr.obs["workforce_mask"].astype(bool)
    assert mask[:, 1:].any()  # some hire or let-go is allowed: there is something to compare
    mine = {"dispatch": np.full((B, M), N), "workforce": np.zeros(B, dtype=np.int64),
            "positioning": np.zeros((B, 2), dtype=np.int64)}
    before = fork(sim)
    v = tr.learner_values(mine)
    assert state_equal(before, sim) == [] and sim.t == before.t  # the copies moved, the episode did not
    weights = np.zeros((B, 2, M))
    weights[:, :, 0] = 1.0  # what positioning index 0 means
    reward = np.zeros(mask.shape)
    for a in range(mask.shape[1]):
        copy = fork(sim)
        reward[:, a] = copy.step({"dispatch": mine["dispatch"], "workforce": np.where(mask[:, a], a, 0),
                                  "positioning": weights})
    want = np.where(mask, reward - reward[:, :1], np.nan)
    np.testing.assert_array_equal(v, want)

    tr.run.config.value_horizon, tr.run.config.value_samples = 6, 2  # the learner acts 5 more steps, two noise samples
    tr.value_fork = None
    state = tr.value_gen.get_state()
    first = tr.learner_values(mine)
    tr.value_gen.set_state(state)
    np.testing.assert_array_equal(tr.learner_values(mine), first)
    assert np.isnan(first[~mask]).all() and not np.isnan(first[mask]).any()
    assert state_equal(before, sim) == []


def test_learner_scores_share_the_dice_across_actions_and_not_across_samples(tmp_path):
    """Copy (b, s, a) of ``learner_scores``: the actions of one sample meet the same noise, the samples differ."""
    tr = Trainer(_cfg(tmp_path, beta0=0.0, workforce_target="improve", value_rollout="learner", value_horizon=12,
                      value_samples=3, value_every=100), progress=False, log=False)
    tr.collect(beta=0.0)
    mask = tr.obs["workforce_mask"].astype(bool)
    B, A = mask.shape
    assert (~mask).any() and mask[:, 1:].any(), "a masked action and an allowed one to compare"
    mine = {"dispatch": np.full((B, tr.sim.M), tr.sim.N), "workforce": np.zeros(B, dtype=np.int64),
            "positioning": np.zeros((B, 2), dtype=np.int64)}
    state = tr.value_gen.get_state()
    scores = tr.learner_scores(mine)
    assert scores.shape == (B, 3, A)
    # a masked action is rolled as the no-op: with the same dice, its 12 steps score the same, bit for bit
    noop = np.broadcast_to(scores[:, :, :1], scores.shape)
    np.testing.assert_array_equal(scores[np.broadcast_to(~mask[:, None, :], scores.shape)],
                                  noop[np.broadcast_to(~mask[:, None, :], scores.shape)])
    assert (scores[:, 0, 0] != scores[:, 1, 0]).any(), "the samples draw their own dice"
    tr.value_gen.set_state(state)
    v = tr.learner_values(mine)  # the same dice again: the mean over the samples, minus the no-op's
    mean = scores.mean(axis=1)
    np.testing.assert_array_equal(v, np.where(mask, mean - mean[:, :1], np.nan))
