"""Each RL library's default path on our environments, plugged in as its documentation shows (docs/envs.md).

PettingZoo's and Gymnasium's own checkers run in tests/envs/test_envs.py; here: PettingZoo's state and render
tests, SuperSuit (SB3's PPO trains on it), Tianshou, TorchRL, and skrl (its IPPO and MAPPO train a few updates);
the ``dev`` extra installs them (RLlib, too heavy for the suite, is run by benchmarks/rllib_ppo.py; PufferLib,
AgileRL and BenchMARL do not install beside our pins, docs/envs.md).
"""

import gymnasium
import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test, render_test, state_test

import wfbench

LIBRARY_OPTIONS = {"observation": "box", "actions": "shared"}  # one Box and one MultiDiscrete for every agent


def test_pettingzoo_state_and_render_tests(strict_warnings):
    state_test(wfbench.env("small"), wfbench.parallel_env("small"))
    render_test(lambda render_mode=None: wfbench.env("small", render_mode=render_mode))
    env = wfbench.parallel_env("small")
    env.reset(seed=0)
    assert env.state_space.contains(env.state()) and env.state().dtype == env.state_space.dtype


def test_library_options_pass_the_pettingzoo_checkers_and_give_one_space_to_all(strict_warnings):
    parallel_api_test(wfbench.parallel_env("small", **LIBRARY_OPTIONS), num_cycles=50)
    parallel_seed_test(lambda: wfbench.parallel_env("small", **LIBRARY_OPTIONS))
    env = wfbench.parallel_env("small", **LIBRARY_OPTIONS)
    assert len({id(env.action_space(a)) for a in env.possible_agents}) == 1
    assert len({id(env.observation_space(a)) for a in env.possible_agents}) == 1


def test_shared_actions_replay_the_own_actions():
    """An agent's part of the shared MultiDiscrete is its own action; the other parts are ignored."""
    own, shared = wfbench.parallel_env("small"), wfbench.parallel_env("small", **LIBRARY_OPTIONS)
    own.reset(seed=2)
    shared.reset(seed=2)
    space = shared.action_space("dispatch")
    space.seed(0)
    M = shared.config.max_facilities
    for _ in range(30):
        joint = {a: space.sample() for a in shared.agents}  # different samples: each agent's other parts differ
        given = {"dispatch": joint["dispatch"][:M], "workforce": joint["workforce"][M],
                 "positioning": joint["positioning"][M + 1 :].reshape(2, M) / 10}
        o1, r1, *_ = own.step(given)
        o2, r2, *_ = shared.step(joint)
        assert r1 == r2
        assert np.array_equal(o2["dispatch"], gymnasium.spaces.flatten(own._dict_space, o1["dispatch"]))
    with pytest.raises(wfbench.ActionError, match=r"action of agent 'dispatch' has shape \(3,\)"):
        shared.step({a: np.zeros(3, np.int64) for a in shared.agents})


def test_flat_info_holds_the_nested_tallies_as_numbers():
    flat, nested = wfbench.parallel_env("small"), wfbench.parallel_env("small", info="nested")
    f, n = flat.reset(seed=1)[1]["dispatch"], nested.reset(seed=1)[1]["dispatch"]
    actions = {"dispatch": np.full(8, 8), "workforce": 1, "positioning": np.full((2, 8), 0.5)}
    f, n = flat.step(actions)[4]["dispatch"], nested.step(actions)[4]["dispatch"]
    assert all(isinstance(v, (int, float)) for v in f.values())
    expect = {"t": n["t"], "seed": n["seed"], **{f"metric_{k}": v for k, v in n["metrics"].items()},
              **{f"count_{k}": v for k, v in n["counts"].items()},
              **{f"step_count_{k}": v for k, v in n["step_counts"].items()}}
    assert f == expect and f["t"] == 1


def test_bad_options_are_named():
    with pytest.raises(ValueError, match=r"actions='same' is not allowed; allowed: 'own', 'shared'"):
        wfbench.parallel_env("small", actions="same")
    with pytest.raises(ValueError, match=r"info='deep' is not allowed; allowed: 'flat', 'nested'"):
        wfbench.parallel_env("small", info="deep")
    with pytest.raises(ValueError, match=r"render_mode 'ansi' is not supported; allowed: None, 'rgb_array', 'human'"):
        wfbench.parallel_env("small", render_mode="ansi")


def test_supersuit_vectorizes_and_flattens_with_its_defaults():
    import supersuit as ss

    env = ss.flatten_v0(wfbench.parallel_env("small", **LIBRARY_OPTIONS))
    vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), 2, num_cpus=0, base_class="gymnasium")
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (6, vec.observation_space.shape[0])
    for _ in range(3):
        obs, rew, term, trunc, _ = vec.step(np.stack([vec.action_space.sample() for _ in range(6)]))
    assert obs.shape[0] == rew.shape[0] == 6 and not term.any()


@pytest.mark.slow
def test_supersuit_vec_env_trains_under_stable_baselines3_with_seed_none():
    """SB3's PPO on SuperSuit's SB3 base class: two updates with ``seed=None``; a seed fails in SB3's ``env.seed``."""
    import supersuit as ss
    from stable_baselines3 import PPO

    def vec_env():
        env = ss.flatten_v0(wfbench.parallel_env("small", **LIBRARY_OPTIONS))
        return ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), 1, num_cpus=0,
                                     base_class="stable_baselines3")

    with pytest.raises(AttributeError, match="'ConcatVecEnv' object has no attribute 'seed'"):
        PPO("MlpPolicy", vec_env(), seed=0, device="cpu")
    model = PPO("MlpPolicy", vec_env(), n_steps=8, batch_size=24, n_epochs=1, seed=None, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(48)  # 3 agents x 8 steps a rollout: two updates
    assert model.num_timesteps == 48
    assert any(not np.array_equal(b.numpy(), p.detach().numpy()) for b, p in zip(before, model.policy.parameters(),
                                                                                  strict=True))


def test_tianshou_pettingzoo_env_takes_the_aec_env():
    from tianshou.env import PettingZooEnv

    env = PettingZooEnv(wfbench.env("small", **LIBRARY_OPTIONS))
    obs, _ = env.reset(seed=0)
    assert env.agents == ["dispatch", "workforce", "positioning"] and obs["agent_id"] == "dispatch"
    for _ in range(6):
        obs, rew, term, trunc, _ = env.step(env.action_space.sample())
    assert len(rew) == 3 and not term


@pytest.mark.filterwarnings("ignore:PettingZoo in TorchRL is tested using version")
def test_torchrl_pettingzoo_wrapper_and_gym_env_with_their_defaults():
    from torchrl.envs import GymWrapper, PettingZooWrapper

    for options in ({}, LIBRARY_OPTIONS):  # the flat info is what its default path needs
        env = PettingZooWrapper(wfbench.parallel_env("small", **options))
        rollout = env.rollout(4)
        assert rollout.batch_size == (4,)
        assert rollout["next", "dispatch", "info", "t"].tolist() == [[1], [2], [3], [4]]
    vec = GymWrapper(gymnasium.make_vec("wfbench/Workforce-v0", 2, scenario="small", observation="box"))
    rollout = vec.rollout(3)
    assert rollout.batch_size == (2, 3)


@pytest.mark.parametrize("positioning", ["2d", "flat"])
def test_skrl_wraps_the_gymnasium_and_pettingzoo_envs_with_its_defaults(positioning):
    """skrl's ``wrap_env`` as its docs show it: auto for a Gymnasium env, ``wrapper="pettingzoo"`` for a Parallel one.

    Its multi-agent wrapper reads the ``observation_spaces`` and ``action_spaces`` dicts; its actions are
    flat tensors, which it unflattens to each agent's space (the positioning ``Box`` as (2, M) or, with
    ``positioning="flat"``, as (2M,)).
    """
    import torch
    from skrl.envs.wrappers.torch import wrap_env

    env = wrap_env(wfbench.parallel_env("small", positioning=positioning), wrapper="pettingzoo", verbose=False)
    obs, _ = env.reset()
    size = gymnasium.spaces.flatdim(env.observation_spaces["dispatch"])
    assert {a: o.shape for a, o in obs.items()} == dict.fromkeys(env.possible_agents, (1, size))
    for a in env.possible_agents:
        env.action_spaces[a].seed(0)
    for _ in range(4):
        actions = {a: torch.as_tensor(env.action_spaces[a].sample()).view(1, -1) for a in env.possible_agents}
        obs, rewards, terminated, truncated, _ = env.step(actions)
    assert env.state()["dispatch"].shape == (1, env.state_space("dispatch").shape[0])
    assert rewards["dispatch"].shape == (1, 1) and not terminated["dispatch"].any()
    assert env.unwrapped.core.sim.t == 4

    single = wrap_env(gymnasium.make("wfbench/Workforce-v0", scenario="small"), verbose=False)
    obs, _ = single.reset()
    single.action_space.seed(0)
    for _ in range(3):
        obs, reward, terminated, truncated, _ = single.step(torch.as_tensor(single.action_space.sample()).view(1, -1))
    assert obs.shape == (1, size) and reward.shape == (1, 1)


# skrl 2.1.1's multi-agent configs expand each field to one value per agent, but refuse a dict whose keys are a
# proper subset of the agents, and the four keyword-argument fields default to {} (a subset of any set): every
# IPPO_CFG() or MAPPO_CFG() fails in MultiAgentCfg.expand. The workaround (docs/envs.md): give them per agent.
SKRL_KWARGS_FIELDS = ("learning_rate_scheduler_kwargs", "observation_preprocessor_kwargs",
                      "state_preprocessor_kwargs", "value_preprocessor_kwargs")


def _skrl_models(env, algorithm):
    """One small policy per agent, of the mixin its action space takes, and a value on the observation (IPPO) or
    on the centralized state (MAPPO)."""
    import torch
    from skrl.models.torch import CategoricalMixin, DeterministicMixin, GaussianMixin, Model, MultiCategoricalMixin

    class Policy(Model):
        def __init__(self, observation_space, action_space, outputs):
            Model.__init__(self, observation_space=observation_space, action_space=action_space, device=env.device)
            self.net = torch.nn.Sequential(torch.nn.Linear(self.num_observations, 32), torch.nn.Tanh(),
                                           torch.nn.Linear(32, outputs))

        def compute(self, inputs, role=""):
            return self.net(inputs["observations"]), {}

    class Categorical(CategoricalMixin, Policy):
        def __init__(self, observation_space, action_space):
            Policy.__init__(self, observation_space, action_space, action_space.n)
            CategoricalMixin.__init__(self)

    class MultiCategorical(MultiCategoricalMixin, Policy):
        def __init__(self, observation_space, action_space):
            Policy.__init__(self, observation_space, action_space, int(action_space.nvec.sum()))
            MultiCategoricalMixin.__init__(self)

    class Gaussian(GaussianMixin, Policy):
        def __init__(self, observation_space, action_space):
            # 2M means, whether the positioning Box is (2, M) or flat: skrl reshapes its flat actions to the space
            Policy.__init__(self, observation_space, action_space, gymnasium.spaces.flatdim(action_space))
            GaussianMixin.__init__(self, clip_actions=True)
            self.log_std = torch.nn.Parameter(torch.zeros(self.num_actions))

        def compute(self, inputs, role=""):
            return self.net(inputs["observations"]), {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self, space, key):
            Model.__init__(self, observation_space=space, device=env.device)
            DeterministicMixin.__init__(self)
            self.key = key
            self.net = torch.nn.Linear(self.num_observations, 1)

        def compute(self, inputs, role=""):
            return self.net(inputs[self.key]), {}

    kinds = {gymnasium.spaces.Discrete: Categorical, gymnasium.spaces.MultiDiscrete: MultiCategorical,
             gymnasium.spaces.Box: Gaussian}
    value = {"IPPO": (env.observation_spaces, "observations"), "MAPPO": (env.state_spaces, "states")}[algorithm]
    return {a: {"policy": kinds[type(env.action_spaces[a])](env.observation_spaces[a], env.action_spaces[a]),
                "value": Value(value[0][a], value[1])} for a in env.possible_agents}


def _skrl_agent(algorithm, env, models, memories, cfg):
    """The agent as skrl's docs build it (``docs/source/snippets/multi_agents_basic_usage.py``)."""
    from skrl.multi_agents.torch.ippo import IPPO
    from skrl.multi_agents.torch.mappo import MAPPO

    return {"IPPO": IPPO, "MAPPO": MAPPO}[algorithm](
        possible_agents=env.possible_agents, models=models, memories=memories, cfg=cfg,
        observation_spaces=env.observation_spaces, state_spaces=env.state_spaces,
        action_spaces=env.action_spaces, device=env.device)


@pytest.mark.parametrize("algorithm", ["IPPO", "MAPPO"])
def test_skrl_default_config_hits_its_expand_bug(algorithm):
    """The bug the workaround is for; when a skrl release fixes it, this fails: drop the workaround and its docs."""
    from skrl.envs.wrappers.torch import wrap_env

    env = wrap_env(wfbench.parallel_env("small"), wrapper="pettingzoo", verbose=False)
    with pytest.raises(ValueError, match=r"Specified keys \(set\(\)\) do not match possible agents"):
        _skrl_agent(algorithm, env, _skrl_models(env, algorithm), None, {})


@pytest.mark.slow
@pytest.mark.parametrize("positioning", ["2d", "flat"])
@pytest.mark.parametrize("algorithm", ["IPPO", "MAPPO"])
def test_skrl_ippo_and_mappo_train_on_the_parallel_env(algorithm, positioning, tmp_path):
    """skrl's IPPO and MAPPO with its SequentialTrainer: three updates of 8 steps each, every agent's policy moved.

    Its experiment folder (TensorBoard, checkpoints) goes to a temporary folder: skrl's default, ``runs/`` of the
    current folder, is where the README's ``wfbench train`` commands write.
    """
    import torch
    from skrl.envs.wrappers.torch import wrap_env
    from skrl.memories.torch import RandomMemory
    from skrl.trainers.torch import SequentialTrainer

    torch.manual_seed(0)
    env = wrap_env(wfbench.parallel_env("small", positioning=positioning), wrapper="pettingzoo", verbose=False)
    models = _skrl_models(env, algorithm)
    rollouts, updates = 8, 3
    memories = {a: RandomMemory(memory_size=rollouts, num_envs=env.num_envs, device=env.device)
                for a in env.possible_agents}
    cfg = {"rollouts": rollouts, "learning_epochs": 1, "mini_batches": 1, "experiment": {"directory": str(tmp_path)},
           **{field: {a: {} for a in env.possible_agents} for field in SKRL_KWARGS_FIELDS}}  # the workaround
    agent = _skrl_agent(algorithm, env, models, memories, cfg)
    before = {a: [p.detach().clone() for p in models[a]["policy"].parameters()] for a in env.possible_agents}
    trainer = SequentialTrainer(env=env, agents=agent, cfg={"timesteps": rollouts * updates, "headless": True,
                                                            "disable_progressbar": True,
                                                            "close_environment_at_exit": False})
    trainer.train()
    assert env.unwrapped.core.sim.t == rollouts * updates
    assert any(tmp_path.iterdir()), "skrl wrote its experiment folder elsewhere than the one given"
    for a in env.possible_agents:
        after = list(models[a]["policy"].parameters())
        assert any(not torch.equal(b, p) for b, p in zip(before[a], after, strict=True)), f"{a}'s policy did not update"
        assert all(torch.isfinite(p).all() for p in after)


@pytest.mark.slow
def test_cleanrl_style_example_trains_from_the_env_id():
    """examples/cleanrl_ppo.py, from the env id: one PPO iteration over one 200-step episode, its return recorded."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "examples" / "cleanrl_ppo.py"
    spec = importlib.util.spec_from_file_location("cleanrl_ppo", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    args = ["--scenario", "small", "--total-timesteps", "200", "--num-envs", "1", "--num-steps", "200",
            "--update-epochs", "1", "--num-minibatches", "2"]
    returns = module.main(args)
    assert len(returns) == 1 and np.isfinite(returns[0]) and returns[0] > 0
