"""The IMPALA trainer's Ray path (issue #14): Ray actors, on a local Ray instance and in-process.

Skipped when the ``ray`` extra is not installed. Starting Ray and the actors' worker
processes (each imports torch and wfbench) costs most of this file's time, so one local
Ray instance (module fixture) serves one real run, through the command line: two Ray
actors, the lag, the counters, the checkpoint as a policy. Resume, Ctrl-C, and who
starts and shuts down Ray run the real ``RemoteActor``s in this process with a stand-in
for Ray's API (``_FakeRay``); the actors' disjoint training seeds and bad settings need
no Ray either.
"""

import math
import sys
from types import SimpleNamespace

import pytest

ray = pytest.importorskip("ray")

import torch  # noqa: E402
from wfbench.policies.neural.model import WorkforceNet, model_config  # noqa: E402

import wfbench  # noqa: E402
from wfbench import policies  # noqa: E402
from wfbench.cli import main  # noqa: E402
from wfbench.train import ray_actors  # noqa: E402
from wfbench.train.impala import Actor, ImpalaConfig, Trainer  # noqa: E402
from wfbench.train.ppo import VARIANTS  # noqa: E402

SMALL = ["--scenario", "small", "--model", "tiny", "--num-envs", "4", "--num-steps", "8", "--seed", "3"]


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray instance for the file; trainers find it running and leave it open."""
    if ray.is_initialized():
        ray.shutdown()
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def test_impala_ray__actors_take_disjoint_training_seeds():
    cfg = ImpalaConfig(scenario="small", model="tiny", seed=3)
    model = WorkforceNet(model_config("tiny", VARIANTS["joint"]))
    scenario = wfbench.scenario("small")

    def taken(index, count, sizes):
        actor = Actor(cfg, scenario, model, torch.device("cpu"), index, count)
        return [s for k in sizes for s in actor.env.take_seeds(k)]

    two = [taken(i, 2, (4, 3)) for i in range(2)]
    assert not set(two[0]) & set(two[1])
    assert all(s >= 1_000_000 for s in two[0] + two[1])  # training seeds only
    assert sorted(two[0] + two[1]) == taken(0, 1, (14,))  # together: the window one actor takes


def test_impala_ray__bad_settings_are_refused_clearly(tmp_path, monkeypatch, capsys):
    def cfg(**kw):
        return ImpalaConfig(**{"scenario": "small", "model": "tiny", "run_dir": str(tmp_path), **kw})

    for kw, message in [
        (dict(address=5), "address 5 is not allowed; allowed: '' \\(no Ray\\), 'local', 'auto', 'ray://HOST:PORT'"),
        (dict(address="http://head:6379"), "address 'http://head:6379' is not allowed; allowed: ''"),
        (dict(address="local", ray_actors=0), "ray_actors = 0 is not allowed; allowed: an integer >= 1"),
        (dict(address="local", ray_actors=1.5), "ray_actors = 1.5 is not allowed; allowed: an integer >= 1"),
        (dict(address="auto", mode="sync"), "mode 'sync' is not allowed with address .*; allowed: async"),
    ]:
        with pytest.raises(ValueError, match=message):
            cfg(**kw).validate()
    cfg(address="ray://head:10001").validate()
    cfg(address="10.0.0.1:6379").validate()
    monkeypatch.setitem(sys.modules, "ray", None)  # as if the extra were not installed
    with pytest.raises(ValueError, match=r"address 'local' needs Ray: pip install 'wfbench\[ray\]'"):
        cfg(address="local").validate()
    monkeypatch.undo()

    # the command line: one line, exit 2; --address is an impala setting only
    argv = ["train", "--steps", "64", "--run-dir", str(tmp_path / "r"), "--no-progress", *SMALL]
    assert main([*argv, "--algo", "ppo", "--address", "local"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: --address does not apply to --algo ppo") and err.count("\n") == 1
    assert main([*argv, "--algo", "impala", "--address", "nowhere"]) == 2
    assert "address 'nowhere' is not allowed" in capsys.readouterr().err


class _Ref:
    def __init__(self, value):
        self.value = value


class _FakeRay:
    """Just enough of Ray's API to run RayActors in this process, logging init, kill and shutdown."""

    exceptions = ray.exceptions

    def __init__(self, initialized):
        self.initialized, self.log = initialized, []

    def is_initialized(self):
        return self.initialized

    def init(self, address, **kw):
        self.log.append(("init", address, kw.get("include_dashboard")))
        self.initialized = True

    def shutdown(self):
        self.log.append(("shutdown",))
        self.initialized = False

    def kill(self, actor):
        self.log.append(("kill",))

    def put(self, value):
        return _Ref(value)

    def get(self, ref):
        return ref.value

    def wait(self, refs, num_returns):
        return refs[:1], refs[1:]

    def remote(self, **kw):
        def actor_class(cls):
            def create(*args):
                obj = cls(*args)
                return SimpleNamespace(ready=_method(obj, "ready"), rollout=_method(obj, "rollout"))

            return SimpleNamespace(remote=create)

        return actor_class


def _method(obj, name):
    """``handle.name.remote(*args)``: run it now; ObjectRef arguments are passed as their values, as Ray does."""
    return SimpleNamespace(
        remote=lambda *args: _Ref(getattr(obj, name)(*(a.value if isinstance(a, _Ref) else a for a in args)))
    )


class _Echo:
    def __init__(self, cfg, index, meta):
        self.index = index

    def ready(self):
        return self.index

    def rollout(self, version, params):
        return {"actor": self.index, "version": version, "w": params["w"]}


@pytest.mark.parametrize("running", [False, True])
def test_impala_ray__starts_and_shuts_down_only_its_own_ray(monkeypatch, running):
    fake = _FakeRay(initialized=running)
    monkeypatch.setattr(ray_actors, "ray", fake)
    cfg = ImpalaConfig(address="local", ray_actors=2)
    actors = ray_actors.RayActors(cfg, _Echo, [None, None], 0, {"w": torch.zeros(1)})
    actors.run(3)  # 3 rollouts in all: one to each actor now, the third when the first comes back
    actors.publish(1, {"w": torch.ones(1)})
    rolls = [actors.next() for _ in range(3)]
    # the third was asked for after the publish: it acts with version 1's parameters
    assert [(r["actor"], r["version"], float(r["w"])) for r in rolls] == [(0, 0, 0.0), (1, 0, 0.0), (0, 1, 1.0)]
    assert not actors.pending and actors.remaining == 0
    actors.close()
    started = [("init", "local", False)] if not running else []
    stopped = [("shutdown",)] if not running else []
    assert fake.log == started + [("kill",), ("kill",)] + stopped
    assert fake.initialized == running


def _cfg(tmp_path, **kw):
    base = dict(scenario="small", model="tiny", num_envs=4, num_steps=8, steps=4 * 8 * 4, eval_every=0,
                checkpoint_every=2, run_dir=str(tmp_path / "run"), seed=3, address="local", ray_actors=2)  # fmt: skip
    return ImpalaConfig(**{**base, **kw})


@pytest.mark.slow
def test_impala_ray__trainer_resume_and_ctrl_c_with_a_stand_in_for_ray(tmp_path, monkeypatch):
    # the whole Ray path in this process: the real RemoteActors, Ray's calls made at once by _FakeRay
    fake = _FakeRay(initialized=False)
    monkeypatch.setattr(ray_actors, "ray", fake)
    tr = Trainer(_cfg(tmp_path), progress=False, log=False)
    assert tr.actor is None and tr.actor_metas == [None, None]
    before = {k: v.clone() for k, v in tr.model.state_dict().items()}
    stats = tr.train()
    assert all(math.isfinite(v) for v in stats.values()), stats
    assert tr.update == 4 and tr.run.global_step == 128 and tr._ray is None
    # both actors asked with update 0's parameters at the start; then each asked again as its rollout is taken
    assert tr.lags == [0, 1, 2, 2]
    assert fake.log == [("init", "local", False), ("kill",), ("kill",), ("shutdown",)]
    assert any(not torch.equal(before[k], v) for k, v in tr.model.state_dict().items())
    latest = torch.load(tmp_path / "run" / "latest.pt", weights_only=False)
    assert [m["seed_cursor"] for m in latest["actors"]] == [4, 4] and latest["seed_cursor"] == 8

    # resume: each actor from its own saved state; Ctrl-C saves latest.pt and shuts the actors and Ray down
    tr = Trainer(_cfg(tmp_path, steps=4 * 8 * 8), resume=tmp_path / "run" / "latest.pt", progress=False, log=False)
    assert tr.update == 4 and tr.lags == [0, 1, 2, 2]
    assert [m["seed_cursor"] for m in tr.actor_metas] == [4, 4]
    assert torch.equal(tr.actor_metas[1]["generator"], latest["actors"][1]["generator"])
    learn = tr.learn

    def interrupted(roll):
        if tr.update == 6:
            raise KeyboardInterrupt
        return learn(roll)

    monkeypatch.setattr(tr, "learn", interrupted)
    fake.log.clear()
    with pytest.raises(KeyboardInterrupt):
        tr.train()
    assert fake.log == [("init", "local", False), ("kill",), ("kill",), ("shutdown",)] and tr._ray is None
    resumed = torch.load(tmp_path / "run" / "latest.pt", weights_only=False)
    assert resumed["update"] == 6 and resumed["global_step"] == 192 and resumed["lags"][:4] == [0, 1, 2, 2]
    # the actors went on from their saved seed cursors (4 each), to the next training seeds
    assert [m["seed_cursor"] for m in resumed["actors"]] == [8, 8]
    with pytest.raises(ValueError, match="made by 2 actor\\(s\\), this run has 3"):
        Trainer(_cfg(tmp_path, ray_actors=3), resume=tmp_path / "run" / "latest.pt")
    with pytest.raises(ValueError, match="made by 2 actor\\(s\\), this run has 1"):
        Trainer(_cfg(tmp_path, address=""), resume=tmp_path / "run" / "latest.pt")


@pytest.mark.slow
def test_impala_ray__cli_trains_on_a_local_ray_instance(local_ray, tmp_path, monkeypatch, capsys):
    run, stats, learn = tmp_path / "run", [], Trainer.learn

    def recorded(self, roll):
        stats.append(learn(self, roll))
        return stats[-1]

    monkeypatch.setattr(Trainer, "learn", recorded)
    # 2 Ray actors x 4 environments x 8 steps: 6 updates of 32 environment steps
    argv = ["train", "--algo", "impala", "--address", "local", "--set", "ray_actors=2", "--steps", "192",
            "--checkpoint-every", "3", "--eval-every", "0", "--run-dir", str(run), "--no-progress",
            "--no-tensorboard", *SMALL]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    assert "trained 192 environment steps (impala)" in capsys.readouterr().out
    assert ray.is_initialized()  # a Ray connection this process already had is left open
    assert len(stats) == 6 and all(math.isfinite(v) for s in stats for v in s.values()), stats

    latest = torch.load(run / "latest.pt", weights_only=False)
    assert latest["update"] == 6 and latest["global_step"] == 192 and latest["algo"] == "impala"
    assert latest["train_config"]["address"] == "local" and latest["train_config"]["ray_actors"] == 2
    # the lag was measured: the two actors' first rollouts both acted with update 0's parameters
    lags = latest["lags"]
    assert len(lags) == 6 and lags[0] == 0 and max(lags) >= 1 and all(0 <= g <= u for u, g in enumerate(lags))
    assert [s["policy_lag"] for s in stats] == lags
    assert len(latest["actors"]) == 2 and all(m["seed_cursor"] >= 4 for m in latest["actors"])  # both acted
    assert (run / "checkpoints" / "update_000003.pt").is_file()
    fresh = Trainer(ImpalaConfig.from_dict(latest["train_config"]), progress=False, log=False)  # the same init
    assert any(not torch.equal(v, latest["model"][k]) for k, v in fresh.model.state_dict().items())

    # the checkpoint is a policy, scored here on a public seed (never on test seeds); best.pt and its
    # public-seed scores during training are the thread path's, tested in test_impala.py
    spec = f"ppo:{run / 'latest.pt'}"
    assert policies.get(spec).mode == "sample"
    df = wfbench.evaluate(spec, "small", seeds=[1000])
    assert df["nsw"].between(0, 1).all() and (df["invalid_actions"] == 0).all()
