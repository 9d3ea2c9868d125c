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
- a bad setting raises a ValueError naming it and what is allowed; test seeds are refused.
"""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import policies  # noqa: E402
import wfbench  # noqa: E402
from wfbench.train.hindsight import HindsightConfig, Trainer  # noqa: E402

TINY = dict(scenario="small", model="tiny", device="cpu", num_envs=3, num_steps=16, burn_in=4, iter_steps=48,
            grad_steps=8, batch_seqs=4, eval_every=0, eval_seeds="public:2")


def _cfg(tmp_path, **kw):
    return HindsightConfig(**{**TINY, "run_dir": str(tmp_path / "run"), **kw})


def test_labels_are_the_oracles_action_in_the_learners_state(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=40, teacher="oracle"), progress=False, log=False)
    res = tr.collect(beta=0.5, record_actions=True)
    trail = res["trail"]
    assert res["stats"]["invalid_labels"] == 0
    seeds = [int(s) for s in trail[0]["seeds"]]
    assert all(s >= 1_000_000 for s in seeds)  # training seeds only

    oracle = policies.get("oracle")  # the registry's composite, built independently of the trainer
    oracle.attach("small")
    oracle.reset(seeds)
    planner = oracle.parts["dispatch"].planner
    sim = wfbench.Simulator("small", seeds)
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


@pytest.mark.parametrize("teacher", ["oracle", "nearest+oracle+oracle"])
def test_pure_teacher_collection_scores_what_the_teacher_scores(tmp_path, teacher):
    tr = Trainer(_cfg(tmp_path, num_envs=2, num_steps=50, teacher=teacher), progress=False, log=False)
    episodes = []
    seeds = None
    while not episodes:
        res = tr.collect(beta=1.0)
        seeds = seeds or [int(s) for s in tr.sim.seeds]
        episodes += res["episodes"]
    df = wfbench.evaluate(teacher, "small", seeds, backend="serial")
    assert episodes[0]["nsw"] == pytest.approx(float(df["nsw"].mean()), abs=1e-12)


def test_supervised_loss_falls(tmp_path):
    tr = Trainer(_cfg(tmp_path, num_steps=32, grad_steps=60, batch_seqs=6, lr=3e-3), progress=False, log=False)
    for _ in range(2):
        tr.data.add(tr.collect(beta=1.0)["chunk"])
    before = tr.dataset_loss()
    stats = tr.learn()
    after = tr.dataset_loss()
    assert np.isfinite(stats["loss"])
    assert after["loss"] < 0.8 * before["loss"], (before, after)


def test_same_seed_same_weights_on_cpu(tmp_path):
    def weights(seed, name):
        tr = Trainer(_cfg(tmp_path, seed=seed, run_dir=str(tmp_path / name)), progress=False, log=False)
        tr.train(iterations=2)
        return tr.model.state_dict()

    a, b, c = weights(0, "a"), weights(0, "b"), weights(1, "c")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_checkpoint_is_a_policy_resumes_and_starts_ppo(tmp_path):
    cfg = _cfg(tmp_path, eval_every=1, steps=48)
    tr = Trainer(cfg, progress=False, log=True)
    tr.train()
    run = tmp_path / "run"
    for name in ("best.pt", "latest.pt", "checkpoints/iter_0001.pt", "config.json", "history.jsonl"):
        assert (run / name).is_file(), name
    assert list((run / "tb").iterdir())
    ckpt = torch.load(run / "best.pt", weights_only=False)
    assert ckpt["best"]["seeds"] == [1000, 1001] and ckpt["default_mode"] == "sample"
    df = wfbench.evaluate(f"ppo:{run / 'best.pt'}", "small", [1000, 1001], backend="serial")
    assert float(df["nsw"].mean()) == pytest.approx(ckpt["best"]["score"], abs=1e-9)
    assert (df["invalid_actions"] == 0).all()

    more = Trainer(HindsightConfig(**{**vars(cfg), "steps": 96}), resume=run / "latest.pt", progress=False,
                   log=False)
    assert more.iteration == 1 and more.global_step == 48
    more.train()
    assert more.iteration == 2 and more.global_step == 96

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
