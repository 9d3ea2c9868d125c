"""The batched Gymnasium VectorEnv and the SB3 VecEnv replay the single environments bit for bit."""

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from stable_baselines3.common.vec_env import DummyVecEnv

import wfbench
from wfbench import ScenarioConfig
from wfbench.envs.gym_env import DispatchEnv, WorkforceEnv
from wfbench.envs.vector import WorkforceVectorEnv
from wfbench.harness.budget import results_only

CONFIG = ScenarioConfig.preset("small").replace(horizon=9)  # several autoresets in a short test
SINGLE = {"workforce": WorkforceEnv, "dispatch": DispatchEnv}


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(a[k].dtype == b[k].dtype and a[k].tobytes() == b[k].tobytes() for k in a)


def same_obs(a, b) -> bool:
    """Dict observations key by key, Box observations (``observation="box"``) as arrays, bit for bit."""
    if isinstance(a, dict):
        return same(a, b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("kind, reward, mode, observation", [
    ("workforce", "nsw", AutoresetMode.SAME_STEP, "dict"), ("dispatch", "nsw", AutoresetMode.SAME_STEP, "dict"),
    ("dispatch", "nsw-no-cost", AutoresetMode.SAME_STEP, "dict"), ("workforce", "nsw", AutoresetMode.NEXT_STEP, "box"),
    ("dispatch", "nsw", AutoresetMode.NEXT_STEP, "dict"), ("workforce", "nsw", AutoresetMode.SAME_STEP, "box"),
])
def test_vector_env_replays_sync_vector_env_of_the_single_env(kind, reward, mode, observation):
    B = 3
    ours = WorkforceVectorEnv(CONFIG, B, kind=kind, reward=reward, autoreset_mode=mode, observation=observation)
    ref = SyncVectorEnv([lambda: SINGLE[kind](CONFIG, reward=reward, observation=observation)] * B,
                        autoreset_mode=mode)
    assert ours.single_observation_space == ref.single_observation_space
    assert ours.single_action_space == ref.single_action_space
    assert ours.metadata["autoreset_mode"] == mode == ours.autoreset_mode
    o1, i1 = ours.reset(seed=40)
    o2, _ = ref.reset(seed=40)
    assert same_obs(o1, o2) and i1["seed"].tolist() == [40, 41, 42]
    ours.action_space.seed(1)
    resets, seeds = 0, i1["seed"]
    for _ in range(2 * CONFIG.horizon + 3):
        masks = ours.action_masks()
        assert masks.shape == (B, int(ours.single_action_space.nvec.sum())) and masks.dtype == bool
        for i, env in enumerate(ref.envs):
            if not ours._pending[i]:  # next-step mode ignores the action of a row whose episode just ended
                assert np.array_equal(masks[i], env.unwrapped.action_masks())
        a = ours.action_space.sample()
        s1, s2 = ours.step(a), ref.step(a)
        assert same_obs(s1[0], s2[0])
        for x, y in zip(s1[1:4], s2[1:4], strict=True):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()
        if s1[3].any():
            resets += 1
            if mode == AutoresetMode.SAME_STEP:
                for i in np.flatnonzero(s1[3]):
                    assert same_obs(s1[4]["final_obs"][i], s2[4]["final_obs"][i])
                assert (s1[4]["seed"] != i1["seed"]).all(), "the new episodes replayed the old seeds"
            else:
                assert (s1[4]["seed"] == seeds).all(), "next-step mode returns the last observation first"
        seeds = s1[4]["seed"]
    assert resets == 2


def test_next_step_autoreset_of_part_of_the_batch_replays_sync_vector_env():
    """Rows out of step (one reset by mask): each starts its new episode on the step after its last."""
    ours = WorkforceVectorEnv(CONFIG, 2, autoreset_mode="next_step")
    ref = SyncVectorEnv([lambda: WorkforceEnv(CONFIG)] * 2, autoreset_mode=AutoresetMode.NEXT_STEP)
    ours.reset(seed=5)
    ref.reset(seed=5)
    ours.action_space.seed(3)
    mask = {"reset_mask": np.array([False, True])}
    for t in range(3 * CONFIG.horizon):
        if t == 4:
            assert same(ours.reset(seed=[11], options=mask)[0], ref.reset(seed=[None, 11], options=mask)[0])
        a = ours.action_space.sample()
        s1, s2 = ours.step(a), ref.step(a)
        assert same(s1[0], s2[0]), t
        for x, y in zip(s1[1:4], s2[1:4], strict=True):
            assert x.tobytes() == y.tobytes(), t


def test_masked_reset_restarts_only_the_masked_environments():
    env = WorkforceVectorEnv(CONFIG, 3)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(4):
        obs, *_ = env.step(env.action_space.sample())
    obs2, info = env.reset(seed=[77], options={"reset_mask": np.array([False, True, False])})
    assert info["t"].tolist() == [4, 0, 4] and info["seed"].tolist() == [0, 77, 2]
    fresh, _ = WorkforceVectorEnv(CONFIG, 1).reset(seed=77)
    for k in obs:
        assert np.array_equal(obs2[k][[0, 2]], obs[k][[0, 2]]), k
        assert np.array_equal(obs2[k][1], fresh[k][0]), k


def test_dispatch_kind_refuses_a_reset_of_part_of_its_batch():
    env = WorkforceVectorEnv(CONFIG, 2, kind="dispatch")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="reset_mask of all True"):
        env.reset(options={"reset_mask": np.array([True, False])})
    _, info = env.reset(seed=[8, 9], options={"reset_mask": np.array([True, True])})
    assert info["seed"].tolist() == [8, 9]


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 0}, r"num_envs = 0 is not allowed; allowed: an integer >= 1"),
    ({"kind": "joint"}, r"kind 'joint' is not allowed; allowed: workforce, dispatch"),
    ({"reward": "x"}, r"reward 'x' is not allowed"),
    ({"fixed": {"workforce": "threshold"}}, r"kind='workforce' learns every decision"),
    ({"autoreset_mode": "later"}, r"autoreset_mode='later' is not allowed; allowed: 'same_step', 'next_step'"),
    ({"observation": "flat"}, r"observation='flat' is not allowed; allowed: 'dict', 'box'"),
])
def test_bad_vector_env_arguments_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        WorkforceVectorEnv(CONFIG, **{"num_envs": 2, **kwargs})


def test_malformed_vector_actions_are_named_and_change_nothing():
    env = WorkforceVectorEnv(CONFIG, 2)
    env.reset(seed=0)
    n = env.single_action_space.shape[0]
    bad = [(np.zeros((2, n + 1), dtype=np.int64), r"action has shape \(2, 26\), expected \(2, 25\)"),
           (np.zeros((2, n)), r"dtype float64; allowed: integers"),
           (np.full((2, n), 11, dtype=np.int64), r"positioning action: 11 at index \(0, 0\)"),
           (np.r_[np.full(n, 0), [-1] + [0] * (n - 1)].reshape(2, n), r"dispatch action: -1 at index \(1, 0\)")]
    for a, message in bad:
        with pytest.raises(wfbench.ActionError, match=message):
            env.step(a)
    assert env.sim.state.t.tolist() == [0, 0]


def test_sb3_vec_env_replays_dummy_vec_env_and_serves_masks():
    from wfbench.envs.sb3 import WorkforceVecEnv

    B = 2
    ours = WorkforceVecEnv(CONFIG, B, seed=5)
    ref = DummyVecEnv([lambda: WorkforceEnv(CONFIG)] * B)
    ref.seed(5)
    assert same(ours.reset(), ref.reset())
    assert ours.has_attr("action_masks") and not ours.has_attr("no_such_thing")
    rng = np.random.default_rng(2)
    for _ in range(CONFIG.horizon + 2):
        masks = np.stack(ours.env_method("action_masks"))
        assert np.array_equal(masks, np.stack(ref.env_method("action_masks")))
        assert np.array_equal(masks[[1]], np.stack(ours.env_method("action_masks", indices=[1])))
        a = rng.integers(0, ours.action_space.nvec, size=(B, len(ours.action_space.nvec)))
        o1, r1, d1, i1 = ours.step(a)
        o2, r2, d2, i2 = ref.step(a)
        assert same(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        for x, y in zip(i1, i2, strict=True):
            assert ("terminal_observation" in x) == ("terminal_observation" in y)
            if "terminal_observation" in x:
                assert same(x["terminal_observation"], y["terminal_observation"])
                assert x["TimeLimit.truncated"] and y["TimeLimit.truncated"]
    with pytest.raises(AttributeError, match="allowed: 'action_masks'"):
        ours.env_method("render")


@pytest.mark.slow
def test_maskable_ppo_learns_through_the_adapter_with_the_entity_extractor():
    from sb3_contrib import MaskablePPO
    from wfbench.policies import Composite

    from wfbench.envs.sb3 import EntitySetExtractor, SB3Policy, WorkforceVecEnv

    env = WorkforceVecEnv(CONFIG, 4, kind="dispatch", seed=0)
    model = MaskablePPO("MultiInputPolicy", env, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu",
                        policy_kwargs={"features_extractor_class": EntitySetExtractor,
                                       "features_extractor_kwargs": {"hidden": 16, "features_dim": 32}})
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(64)
    assert any(not np.array_equal(a.numpy(), b.detach().numpy()) for a, b in zip(before, model.policy.parameters(),
                                                                                 strict=True))
    policy = Composite(dispatch=SB3Policy(model, CONFIG, kind="dispatch"), workforce="threshold",
                       positioning="spatial")
    df = wfbench.evaluate(policy, CONFIG, seeds=[0, 1])
    assert len(df) == 2 and np.isfinite(df["nsw"]).all()
    assert df["invalid_dispatch_not_requesting"].sum() == 0, "masked actions sent someone to a working facility"


def test_the_vector_env_and_the_core_never_import_torch():
    import subprocess
    import sys

    probe = ("import sys, wfbench, wfbench.envs.vector\n"
             "print('torch' in sys.modules, 'stable_baselines3' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"], out


def test_sb3_wrappers_see_whole_episodes_through_the_adapter():
    from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor

    from wfbench.envs.sb3 import WorkforceVecEnv

    env = VecCheckNan(VecMonitor(WorkforceVecEnv(CONFIG, 2, kind="dispatch", seed=3)), raise_exception=True)
    env.reset()
    total, episodes = np.zeros(2), []
    for _ in range(CONFIG.horizon):
        masks = np.stack(env.env_method("action_masks")).reshape(2, CONFIG.max_facilities, -1)
        _, r, done, infos = env.step(masks.shape[-1] - 1 - np.argmax(masks[..., ::-1], axis=-1))
        total += r
        episodes += [info["episode"] for info in infos if "episode" in info]
    assert done.all() and len(episodes) == 2
    assert [e["l"] for e in episodes] == [CONFIG.horizon] * 2
    assert np.allclose([e["r"] for e in episodes], total, atol=1e-4)


def test_plain_ppo_on_the_joint_kind_plays_all_three_decisions_in_evaluate():
    from stable_baselines3 import PPO

    from wfbench.envs.sb3 import EntitySetExtractor, SB3Policy, WorkforceVecEnv

    env = WorkforceVecEnv(CONFIG, 2, seed=1_000_000)
    model = PPO("MultiInputPolicy", env, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"features_extractor_class": EntitySetExtractor,
                               "features_extractor_kwargs": {"hidden": 8, "features_dim": 16}})
    model.learn(16)
    policy = SB3Policy(model, CONFIG)
    assert policy.decisions == ("dispatch", "workforce", "positioning") and not policy._masked
    df = wfbench.evaluate(policy, CONFIG, seeds=[0, 1])
    again = wfbench.evaluate(policy, CONFIG, seeds=[0, 1])
    assert results_only(df).equals(results_only(again)), "a deterministic policy gave two results"
    assert df["hires"].sum() + df["releases"].sum() + df["invalid_hire_no_slot"].sum() \
        + df["invalid_release_none"].sum() > 0, "the workforce decision never acted"


def test_make_vec_builds_the_batched_env_and_gymnasium_vector_wrappers_take_it():
    """The ids' vector entry point; NormalizeObservation (next-step only) and TorchRL read the declared mode."""
    import gymnasium
    from gymnasium.wrappers.vector import FlattenObservation, NormalizeObservation

    env = gymnasium.make_vec("wfbench/Workforce-v0", num_envs=2, scenario="small")
    assert isinstance(env.unwrapped, WorkforceVectorEnv) and env.unwrapped.kind == "workforce"
    assert env.unwrapped.autoreset_mode == AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match="NEXT_STEP"):  # Gymnasium's observation wrappers refuse same-step
        FlattenObservation(env)
    next_step = gymnasium.make_vec("wfbench/Workforce-v0", 2, scenario="small", autoreset_mode="next_step")
    flat = FlattenObservation(next_step)
    obs, _ = flat.reset(seed=0)
    assert obs.shape == (2, flat.single_observation_space.shape[0])
    dispatch = gymnasium.make_vec("wfbench/Dispatch-v0", num_envs=2, vectorization_mode="vector_entry_point",
                                  scenario=CONFIG, observation="box", autoreset_mode="next_step")
    assert dispatch.unwrapped.kind == "dispatch"
    norm = NormalizeObservation(dispatch)
    obs, _ = norm.reset(seed=0)
    for _ in range(CONFIG.horizon + 1):
        obs, reward, _, truncated, _ = norm.step(norm.action_space.sample())
    assert obs.shape == (2, dispatch.single_observation_space.shape[0]) and np.isfinite(obs).all()
    assert not truncated.any() and (reward == 0).all(), "the step after the horizon starts the new episodes"
    sync = gymnasium.make_vec("wfbench/Workforce-v0", num_envs=2, vectorization_mode="sync", scenario="small")
    assert isinstance(sync, SyncVectorEnv)
