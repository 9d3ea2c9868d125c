"""Distillation (``wfbench train --algo distill``): the network imitates a deployable teacher on its own states.

- a teacher that reads the future is refused in one line naming the rule, from Python and
  from the command line; so are an unknown teacher and a network other than the scale-free one;
- a tiny run raises the network's agreement with its teacher on public seeds no batch trains on
  (the likelihood of the teacher's choices);
- the teacher's own play is labelled once: a second run replays the labels from the cache,
  and they equal the labels the teacher gives when asked;
- a run's checkpoints record ``distill``, load as ``distill:PATH`` and resume.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from wfbench import policies
from wfbench.cli import main
from wfbench.train.distill import DistillConfig, LabelCache, Trainer
from wfbench.train.runs import fit

TINY = {"scenario": "small", "teacher": "heuristic", "num_envs": 2, "num_steps": 8, "iter_steps": 32,
        "grad_steps": 10, "batch_seqs": 4, "eval_every": 0, "dataset_steps": 1024, "teacher_batches": 1, "burn_in": 2}


@pytest.mark.parametrize("teacher", ["oracle", "oracle-planner", "nearest+oracle+oracle", "oracle-dispatch"])
def test_a_teacher_that_reads_the_future_is_refused(teacher, tmp_path):
    with pytest.raises(ValueError) as info:
        DistillConfig(**{**TINY, "teacher": teacher}, run_dir=str(tmp_path)).check()
    line = str(info.value)
    assert "\n" not in line and f"teacher {teacher!r} reads the future" in line, line
    assert "--algo hindsight" in line, line


def test_the_command_line_refuses_an_oracle_teacher_in_one_line(tmp_path, capsys):
    code = main(["train", "--algo", "distill", "--teacher", "oracle", "--scenario", "small", "--steps", "64",
                 "--no-progress", "--run-dir", str(tmp_path / "run")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "teacher 'oracle' reads the future" in lines[0], err
    assert not (tmp_path / "run").exists()  # nothing trained, nothing written


@pytest.mark.parametrize(("settings", "expected"), [
    ({"teacher": "rollout-solver-tunned"}, "teacher 'rollout-solver-tunned' is not a policy: unknown policy"),
    ({"teacher": ""}, "teacher '' is not allowed; allowed: the name of a deployable policy"),
    ({"model": "small"}, "model 'small' is not allowed for distill; allowed: scalefree"),
    ({"teacher_batches": -1}, "teacher_batches = -1 is not allowed; allowed: an integer >= 0"),
    ({"workforce_target": "values"}, "workforce_target = 'values' is not allowed for distill"),
])
def test_bad_settings_get_one_line(settings, expected, tmp_path):
    with pytest.raises(ValueError) as info:
        DistillConfig(**{**TINY, **settings}, run_dir=str(tmp_path)).check()
    assert "\n" not in str(info.value) and expected in str(info.value), str(info.value)


@pytest.mark.slow
def test_a_tiny_run_raises_its_agreement_with_the_teacher(tmp_path):
    cfg = DistillConfig(**{**TINY, "num_envs": 4, "num_steps": 16, "iter_steps": 256, "steps": 256 * 6,
                           "grad_steps": 30, "batch_seqs": 8, "dataset_steps": 4096},
                        run_dir=str(tmp_path / "run"), label_cache="off", seed=3)
    trainer = Trainer(cfg, progress=False, log=False)
    before = trainer.agreement(steps=100)  # public seeds: states no training batch visits
    trainer.train()
    after = trainer.agreement(steps=100)
    nll = {k: (before[f"nll_{k}"], after[f"nll_{k}"]) for k in ("dispatch", "workforce", "positioning")}
    assert all(a < b for b, a in nll.values()) and nll["dispatch"][1] < 0.5 * nll["dispatch"][0], nll
    # the greedy choices, near the heuristic's already on small, do not move away from it
    assert after["dispatch"] >= before["dispatch"] and after["workforce"] >= before["workforce"], (before, after)


def _first_labels(trainer: Trainer) -> list[dict[str, np.ndarray]]:
    res = trainer.collect(trainer.beta(), record_actions=True)
    return [step["label"] for step in res["trail"]]


@pytest.mark.slow
def test_the_teachers_own_play_is_labelled_once_and_replayed_the_same(tmp_path):
    cache = tmp_path / "labels"
    runs = {}
    for seed, folder in ((1, cache), (2, cache), (3, "off")):
        cfg = DistillConfig(**{**TINY, "scenario": "small", "num_steps": 200}, run_dir=str(tmp_path / f"r{seed}"),
                            label_cache=str(folder), seed=seed)
        trainer = Trainer(cfg, progress=False, log=False)
        labels = _first_labels(trainer)  # one chunk of 200 steps: the whole demonstration episode
        runs[seed] = (trainer, labels)
    first, second, fresh = runs[1], runs[2], runs[3]
    assert first[0].cache_stats == {"hits": 0, "misses": 1} and second[0].cache_stats == {"hits": 1, "misses": 0}
    assert fresh[0].labels is None  # label_cache off: the teacher is asked
    assert list((cache / "heuristic").glob("small*.npz")), list(cache.rglob("*"))
    for a, b, c in zip(first[1], second[1], fresh[1], strict=True):
        for k in a:
            assert np.array_equal(a[k], b[k]) and np.array_equal(a[k], c[k]), k
    # the demonstration seeds are every run's; the batches after it are the run's own
    assert np.array_equal(first[0].sim.seeds, second[0].sim.seeds)
    for trainer, _ in (first, second):
        trainer.collect(trainer.beta())
    assert not np.array_equal(first[0].sim.seeds, second[0].sim.seeds)


def test_a_changed_world_is_a_new_cache_file(tmp_path):
    from wfbench.scenarios.resolve import resolve_scenario

    small = resolve_scenario("small")
    cache = LabelCache(tmp_path)
    assert cache.path("heuristic", small, [1, 2]) != cache.path("heuristic", small.replace(horizon=100), [1, 2])
    assert cache.path("heuristic", small, [1, 2]) != cache.path("heuristic", small, [1, 3])
    assert cache.path("heuristic", small, [1, 2]) != cache.path("solver", small, [1, 2])


@pytest.mark.slow
def test_checkpoints_record_distill_load_as_a_policy_and_resume(tmp_path):
    run = tmp_path / "run"
    settings = {**TINY, "steps": 64, "checkpoint_every": 1, "run_dir": str(run), "label_cache": "off",
                "eval_every": 2, "eval_seeds": "public:1"}
    fit("distill", progress=False, log=False, **settings)
    latest = run / "latest.pt"
    assert torch.load(latest, weights_only=False)["algo"] == "distill"
    best = torch.load(run / "best.pt", weights_only=False)["best"]
    assert best["mode"] == "greedy" and best["score"] == best["greedy"], best  # selected on the greedy score
    pol = policies.get(f"distill:{run / 'best.pt'}@greedy")
    assert pol.mode == "greedy" and set(pol.decisions) == {"dispatch", "workforce", "positioning"}
    trainer = fit(resume=latest, progress=False, log=False, steps=128)
    assert trainer.run.global_step == 128 and trainer.iteration == 4


@pytest.mark.slow
def test_each_history_line_records_the_beta_its_iteration_mixed_with_also_after_a_resume(tmp_path, monkeypatch):
    used: dict[int, list[float]] = {}  # iteration -> the probabilities its steps mixed with
    mix = Trainer.mix_beta

    def recording(self, beta):
        value = mix(self, beta)
        used.setdefault(self.iteration, []).append(value)
        return value

    monkeypatch.setattr(Trainer, "mix_beta", recording)
    run = tmp_path / "run"
    # one iteration = one episode batch (2 environments x small's 200 steps): each starts a batch, so the
    # schedule moves at every iteration; the first batch is the teacher's own play (beta = 1)
    settings = {**TINY, "iter_steps": 400, "steps": 800, "checkpoint_every": 1, "run_dir": str(run),
                "label_cache": "off", "beta0": 0.5}
    fit("distill", progress=False, log=False, **settings)
    trainer = fit(resume=run / "latest.pt", progress=False, log=False, steps=1200)
    lines = [json.loads(line) for line in (run / "history.jsonl").read_text().splitlines()]
    assert [line["update"] for line in lines] == [1, 2, 3] and trainer.iteration == 3
    logged = [line["beta"] for line in lines]
    assert logged == [used[i][0] for i in range(3)], (logged, {i: sorted(set(v)) for i, v in used.items()})
    assert all(len(set(used[i])) == 1 for i in range(3)), used  # one batch an iteration: one probability
    assert logged == [1.0, 0.25, 0.125], logged  # teacher's play, then beta0 * decay ** (batch - 1 + 1)
