"""Data-parallel PPO (``wfbench.train.shards``): 1 and 2 processes train the same bits; bad settings say so.

A tiny run (``small``, the ``tiny`` network, 4 environments as 2 shards, T = 8) two updates
long, in one process and in two: ``latest.pt`` equal tensor for tensor (weights, both
optimizers, torch's random state, each shard's sampling generator) and in every counter
and normalizer; then each resumed for a third update, crosswise (the two-process run's
checkpoint in one process and the other way round): equal again.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import torch

from wfbench.cli import build_parser
from wfbench.cli import main as cli_main
from wfbench.cli.train import two_processes_likely
from wfbench.train import standby
from wfbench.train.ppo import TrainConfig, Trainer

# what two runs of the same bits may differ in: when, how long and how (their processes) they ran
RUN_ONLY = {"train_wall_s", "train_hardware", "train_config", "git_commit"}


def _cfg(run_dir, procs: int, updates: int = 2) -> TrainConfig:
    return TrainConfig(scenario="small", model="tiny", num_envs=4, num_steps=8, steps=4 * 8 * updates, shards=2,
                       procs=procs, eval_every=0, checkpoint_every=1, device="cpu", threads=1, seed=3,
                       run_dir=str(run_dir))


def _leaves(x, path=""):
    """Every leaf of a checkpoint (nested dicts and lists) by its path."""
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _leaves(v, f"{path}/{k}")
    elif isinstance(x, list | tuple):
        for i, v in enumerate(x):
            yield from _leaves(v, f"{path}/{i}")
    else:
        yield path, x


def _assert_same(a, b) -> None:
    x, y = (dict(_leaves(torch.load(p, map_location="cpu", weights_only=False))) for p in (a, b))
    assert x.keys() == y.keys()
    tensors = 0
    for k in x:
        if k.split("/")[1] in RUN_ONLY:
            continue
        if isinstance(x[k], torch.Tensor):
            tensors += 1
            assert x[k].dtype == y[k].dtype and torch.equal(x[k], y[k]), k
        else:
            assert x[k] == y[k], k
    assert tensors > 50  # the weights and Adam's moments are in it


def _train(run_dir, procs: int, updates: int = 2, resume=None) -> Trainer:
    tr = Trainer(_cfg(run_dir, procs, updates), resume=resume, progress=False, log=False)
    assert (tr.group.shards, tr.group.procs) == (2, procs)
    tr.train()
    assert tr.worker is None  # the run took its steps: the second process went
    return tr


@pytest.mark.slow
def test_procs__one_and_two_processes_train_the_same_bits_and_resume_crosswise(tmp_path):
    one, two = _train(tmp_path / "one", 1), _train(tmp_path / "two", 2)
    assert one.update == two.update == 2 and one.run.global_step == two.run.global_step == 64
    _assert_same(tmp_path / "one" / "latest.pt", tmp_path / "two" / "latest.pt")
    assert json.loads((tmp_path / "two" / "config.json").read_text())["computed_as"] == {"shards": 2, "procs": 2}
    _assert_same(tmp_path / "one" / "checkpoints" / "update_000001.pt",
                 tmp_path / "two" / "checkpoints" / "update_000001.pt")
    ckpt = torch.load(tmp_path / "two" / "latest.pt", weights_only=False)
    first, second = ckpt["shards"]
    assert not torch.equal(first["generator"], second["generator"]), "each shard samples from its own stream"
    assert first["ret_std"] != second["ret_std"], "each shard normalizes its own rewards"
    fresh = Trainer(_cfg(tmp_path / "fresh", 1), progress=False, log=False).model.state_dict()
    assert any(not torch.equal(v, fresh[k]) for k, v in one.model.state_dict().items()), "the updates moved nothing"
    # resumed for a third update, each from the other's checkpoint
    _train(tmp_path / "one-then-two", 2, 3, resume=tmp_path / "one" / "latest.pt")
    _train(tmp_path / "two-then-one", 1, 3, resume=tmp_path / "two" / "latest.pt")
    _assert_same(tmp_path / "one-then-two" / "latest.pt", tmp_path / "two-then-one" / "latest.pt")


@pytest.mark.slow
def test_procs__the_second_process_ends_at_once_when_let_go(tmp_path):
    # close() waits for the worker; it skips the interpreter's finalization (1.7 s of the 2-core VM) after its
    # exit handlers, with status 0
    tr = Trainer(_cfg(tmp_path, 2, 1), progress=False, log=False)
    worker = tr.worker
    tr.close()
    assert tr.worker is None and worker.proc.returncode == 0
    leave = ("import atexit; from wfbench.train import shards; atexit.register(print, 'handler ran'); "
             "print('written', end=' '); shards._leave(); print('never')")
    done = subprocess.run([sys.executable, "-c", leave], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.split() == ["written", "handler", "ran"]


@pytest.mark.slow
def test_procs__a_standby_started_ahead_is_the_second_process_or_let_go(tmp_path):
    # wfbench train starts the second process ahead when it guesses two (its imports overlap the first's)
    standby.start("wfbench.train.ppo")
    ahead = standby._standby
    tr = Trainer(_cfg(tmp_path / "two", 2, 1), progress=False, log=False)
    assert tr.worker.proc is ahead and standby._standby is None
    tr.close()
    assert ahead.returncode == 0
    # a run of one process lets it go: it ends on its own, unused
    standby.start("wfbench.train.ppo")
    ahead = standby._standby
    Trainer(_cfg(tmp_path / "one", 1, 1), progress=False, log=False)
    assert standby._standby is None and ahead.wait(timeout=120) == 0


@pytest.mark.parametrize(("flags", "likely"), [
    (["--scenarios", "suite-v1:train"], True),  # the default across worlds: 128 environments, 2 processes
    (["--num-envs", "64"], True),
    ([], False),  # one world's default 32: one shard
    (["--scenarios", "suite-v1:train", "--procs", "1"], False),
    (["--scenarios", "suite-v1:train", "--device", "cuda"], False),
    (["--scenarios", "suite-v1:train", "--algo", "impala"], False),
    (["--scenarios", "suite-v1:train", "--num-envs", "32"], False),
])
def test_procs__wfbench_train_guesses_two_processes_from_its_flags(flags, likely):
    args = build_parser().parse_args(["train", *flags])
    assert two_processes_likely(args) is (likely and len(os.sched_getaffinity(0)) >= 2)


def test_procs__the_batchs_shards_by_default(tmp_path):
    def cfg(**kw):
        return TrainConfig(**{"scenario": "small", "model": "tiny", "run_dir": str(tmp_path), **kw})

    assert cfg(num_envs=64).shard_count() == 2 and cfg(num_envs=32).shard_count() == 1  # auto: 2 from 64 on
    assert cfg(num_envs=66).shard_count() == 1  # 33 a shard cannot take half of each of 2 minibatches
    assert cfg(num_envs=8, shards=2).shard_count() == 2
    assert cfg(num_envs=64, procs=1).proc_count() == 1 and cfg(num_envs=32).proc_count() == 1
    assert TrainConfig.from_dict({"num_envs": 128}).shards == 1, "a run saved before shards: one shard"


@pytest.mark.parametrize(("flags", "says"), [
    (["--procs", "3"], "procs = 3 is not allowed; allowed: 0 (auto), 1 or 2"),
    (["--procs", "2", "--num-envs", "4"], "procs = 2 with one shard (num_envs = 4, shards = 0) is not allowed"),
    (["--num-envs", "6", "--set", "shards=2"], "shards = 2 with num_envs = 6"),
])
def test_procs__a_bad_setting_is_one_line_naming_what_is_allowed(tmp_path, capsys, flags, says):
    code = cli_main(["train", "--scenario", "small", "--model", "tiny", "--steps", "16", "--num-steps", "8",
                     "--device", "cpu", "--run-dir", str(tmp_path / "run"), "--no-progress", "--no-tensorboard",
                     *flags])
    err = capsys.readouterr().err
    assert code == 2 and says in err and "allowed:" in err
    assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "run").exists()
