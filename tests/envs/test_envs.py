"""The peers' own checkers on our environments, through wfbench.testing.check_env (what a submitter runs)."""

import gymnasium
import numpy as np
import pytest

import wfbench
from wfbench.testing import check_env

SCENARIOS = ["small", "paper-64"]
GYMNASIUM_AND_SB3 = ("gymnasium.utils.env_checker.check_env", "stable_baselines3.common.env_checker.check_env")


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_api(scenario):
    assert check_env(wfbench.parallel_env(scenario), num_cycles=200) == ("pettingzoo.test.parallel_api_test",)


@pytest.mark.parametrize("fixed", [None, {"workforce": "threshold", "positioning": "heuristic"}])
def test_parallel_seed(fixed):
    ran = check_env(lambda: wfbench.parallel_env("small", fixed=fixed))
    assert ran == ("pettingzoo.test.parallel_api_test", "pettingzoo.test.parallel_seed_test")


def test_aec_api():
    assert check_env(wfbench.env("small"), num_cycles=100) == ("pettingzoo.test.api_test",)


@pytest.mark.parametrize("env_id", ["wfbench/Workforce-v0", "wfbench/Dispatch-v0"])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_gymnasium_and_sb3_checkers(env_id, scenario):
    assert check_env(gymnasium.make(env_id, scenario=scenario)) == GYMNASIUM_AND_SB3


@pytest.mark.parametrize("options", [{}, {"actions": "shared"}, {"positioning": "flat"},
                                     {"fixed": {"workforce": "threshold"}}])
def test_space_dicts_hold_the_space_objects_of_each_agent(options):
    """ParallelEnv declares observation_spaces and action_spaces; skrl's multi-agent wrapper reads them."""
    env = wfbench.parallel_env("small", **options)
    assert list(env.observation_spaces) == list(env.action_spaces) == env.possible_agents
    for a in env.possible_agents:
        assert env.observation_spaces[a] is env.observation_space(a)
        assert env.action_spaces[a] is env.action_space(a)
    assert "workforce" not in env.action_spaces if "fixed" in options else len(env.action_spaces) == 3


def test_flat_positioning_passes_the_checkers():
    """positioning="flat": PettingZoo's API and seed tests on the Parallel and AEC environments.

    (Gymnasium's and SB3's checkers are for the Gymnasium ids, whose positioning is part of a MultiDiscrete.)
    """
    env = wfbench.parallel_env("small", positioning="flat")
    assert env.action_space("positioning") == gymnasium.spaces.Box(0.0, 1.0, shape=(16,), dtype=np.float32)
    ran = check_env(lambda: wfbench.parallel_env("small", positioning="flat"), num_cycles=100)
    assert ran == ("pettingzoo.test.parallel_api_test", "pettingzoo.test.parallel_seed_test")
    ran = check_env(lambda: wfbench.env("small", positioning="flat", observation="box"), num_cycles=100)
    assert ran == ("pettingzoo.test.api_test", "pettingzoo.test.seed_test")


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_flat_positioning_plays_the_episode_of_the_2d_positioning_bit_for_bit(dtype):
    """The same seed and the same actions, positioning given flat and as (2, M): the same episode, every bit."""
    episodes = []
    for positioning in ("2d", "flat"):
        env = wfbench.parallel_env("small", positioning=positioning, info="nested")
        rng = np.random.default_rng(7)
        obs, infos = env.reset(seed=3)
        trail = [(obs, infos)]
        while env.agents:
            weights = (rng.random((2, 8)) * (rng.random((2, 8)) < 0.7)).astype(dtype)
            actions = {"dispatch": rng.integers(0, 9, size=8), "workforce": int(rng.integers(0, 7)),
                       "positioning": weights if positioning == "2d" else weights.ravel()}
            trail.append(env.step(actions))
        episodes.append(trail)
    two_d, flat = episodes
    assert len(two_d) == len(flat) == 201
    hires = 0
    for a, b in zip(two_d, flat, strict=True):
        for agent in a[0]:
            assert a[0][agent].keys() == b[0][agent].keys()
            assert all(a[0][agent][k].tobytes() == b[0][agent][k].tobytes() for k in a[0][agent])
        assert a[1:] == b[1:]  # rewards, terminations, truncations, infos
        hires += a[-1]["workforce"]["step_counts"]["hires"]
    assert hires > 0, "no hire read the positioning weights: the test would not see a difference"


def test_bad_positioning_options_and_actions_are_named():
    with pytest.raises(ValueError, match=r"^positioning='1d' is not allowed; allowed: '2d', 'flat'$"):
        wfbench.parallel_env("small", positioning="1d")
    with pytest.raises(ValueError, match=r"^positioning='flat' is not allowed with actions='shared', whose positioning "
                                         r"is already flat \(2M levels of the shared MultiDiscrete\); allowed: "
                                         r"positioning='flat' with actions='own'$"):
        wfbench.env("small", positioning="flat", actions="shared")
    env = wfbench.parallel_env("small", positioning="flat")
    env.reset(seed=0)
    ok = {"dispatch": np.full(8, 8), "workforce": 0}
    with pytest.raises(wfbench.ActionError, match=r"^action of agent 'positioning' has shape \(2, 8\); allowed: "
                                                  r"\(16,\), the flat positioning Box \(positioning='flat'\)$"):
        env.step({**ok, "positioning": np.zeros((2, 8))})
    with pytest.raises(wfbench.ActionError, match=r"positioning action: nan at index \(0, 1, 2\) is not allowed"):
        env.step({**ok, "positioning": np.r_[np.zeros(10), np.nan, np.zeros(5)]})
    assert env.core.sim.t == 0


def test_fixed_agents_leave_the_agent_list():
    env = wfbench.parallel_env("small", fixed={"workforce": "threshold", "positioning": "spatial"})
    obs, _ = env.reset(seed=3)
    assert env.agents == ["dispatch"]
    assert set(obs) == {"dispatch"}


def test_fixed_agent_action_is_refused():
    env = wfbench.parallel_env("small", fixed={"workforce": "threshold"})
    env.reset(seed=0)
    with pytest.raises(wfbench.ActionError, match="fixed"):
        env.core.step({"workforce": 0})


def test_unknown_fixed_policy_names_what_exists():
    with pytest.raises(ValueError, match="available: .*threshold"):
        wfbench.parallel_env("small", fixed={"workforce": "nope"})


def test_masks_allow_only_open_requests_and_free_people():
    env = wfbench.parallel_env("paper-64")
    obs, _ = env.reset(seed=1)
    for _ in range(60):
        o = obs["dispatch"]
        mask = o["dispatch_mask"]
        assert (mask[:, -1] == 1).all(), "the no-op is always allowed"
        allowed = mask[:, :-1].astype(bool)
        assert (allowed == (o["requesting"][:, None].astype(bool) & o["dispatchable"][None, :].astype(bool))).all()
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, *_ = env.step(actions)


def test_dispatch_env_with_masked_actions_reports_no_invalid_dispatch():
    env = gymnasium.make("wfbench/Dispatch-v0", scenario="small", info="nested").unwrapped
    env.reset(seed=5)
    env.action_space.seed(5)
    M, N = env.M, env.N
    total = 0
    for _ in range(150):
        mask = env.action_masks().reshape(M, N + 1)
        action = env.action_space.sample(mask=tuple(m.astype(np.int8) for m in mask))
        _, _, _, trunc, info = env.step(action)
        total += info["step_counts"]["invalid_dispatch_not_requesting"] + info["step_counts"][
            "invalid_dispatch_unavailable"]
        if trunc:
            break
    assert total == 0


def test_render_draws_the_grid():
    env = wfbench.parallel_env("small", render_mode="rgb_array")
    env.reset(seed=2)
    img = env.render()
    assert img.shape[2] == 3 and img.dtype == np.uint8
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 3, "the frame is not blank"


def test_nsw_no_cost_reward_is_the_geometric_mean_of_two_utilities():
    env = gymnasium.make("wfbench/Dispatch-v0", scenario="small", reward="nsw-no-cost").unwrapped
    env.reset(seed=0)
    _, r, *_ = env.step(np.full(env.M, env.N))
    last = env.core.sim.state.last[0]
    assert r == pytest.approx(float((last[5] * last[6]) ** 0.5))


def test_observations_are_fresh_copies_that_later_steps_leave_alone():
    env = wfbench.parallel_env("paper-64")
    obs, _ = env.reset(seed=2)
    for a in env.agents:
        env.action_space(a).seed(2)
    kept = [(obs, {a: {k: v.copy() for k, v in o.items()} for a, o in obs.items()})]
    for _ in range(30):
        obs, *_ = env.step({a: env.action_space(a).sample() for a in env.agents})
        kept.append((obs, {a: {k: v.copy() for k, v in o.items()} for a, o in obs.items()}))
    changed = 0
    for (returned, snapshot), (later, _) in zip(kept, kept[1:], strict=False):
        for a in returned:
            assert returned[a].keys() == snapshot[a].keys()
            for k in returned[a]:
                assert np.array_equal(returned[a][k], snapshot[a][k]), f"step overwrote {a}/{k} of an earlier step"
                changed += not np.array_equal(returned[a][k], later[a][k])
    assert changed > 0, "the observation never changed: the test would not see an overwrite"


def test_env_accepts_every_action_form_alike_and_names_malformed_ones():
    """Plain int64 / float arrays take the environment's buffer path, other forms the numpy
    path: all give the same episode; a malformed action names the agent and the index and
    does not advance the episode."""
    rng = np.random.default_rng(11)
    M, N = 50, 50
    steps = [(rng.integers(0, N + 1, size=M), int(rng.integers(0, 7)),
              rng.random((2, M)).astype(np.float32).astype(np.float64)) for _ in range(60)]
    forms = [
        lambda d, w, p: {"dispatch": d, "workforce": np.int64(w), "positioning": p},
        lambda d, w, p: {"dispatch": d.tolist(), "workforce": w, "positioning": p.tolist()},
        lambda d, w, p: {"dispatch": d.astype(np.int32), "workforce": np.array(w, dtype=np.uint8),
                         "positioning": p.astype(np.float32)},
        lambda d, w, p: {"dispatch": d.astype(float), "workforce": float(w), "positioning": p},
    ]
    runs = []
    for form in forms:
        env = wfbench.parallel_env("paper-64")
        env.reset(seed=4)
        trail = []
        for d, w, p in steps:
            obs, rew, _, _, info = env.step(form(d, w, p))
            trail.append((obs["dispatch"]["personnel"].tobytes(), rew["dispatch"], info["dispatch"]))
        runs.append(trail)
    assert all(r == runs[0] for r in runs[1:])

    env = wfbench.parallel_env("paper-64")
    env.reset(seed=4)
    ok = {"dispatch": np.full(M, N), "workforce": 0, "positioning": np.zeros((2, M))}
    bad = [({"dispatch": np.r_[np.full(M - 1, N), N + 1]}, r"dispatch action: 51 at index \(0, 49\)"),
           ({"workforce": np.int64(-1)}, r"workforce action: -1 at index \(0,\)"),
           ({"positioning": np.full((2, M), np.nan)}, r"positioning action: nan at index \(0, 0, 0\)"),
           ({"dispatch": np.full(M + 1, N)}, r"dispatch action has shape \(1, 51\)")]
    for change, message in bad:
        with pytest.raises(wfbench.ActionError, match=message):
            env.step({**ok, **change})
        assert env.core.sim.t == 0


def test_info_counts_add_up_over_the_steps():
    env = wfbench.parallel_env("paper-64", fixed={"positioning": "spatial"}, info="nested")
    _, infos = env.reset(seed=6)
    assert set(infos["dispatch"]["step_counts"].values()) == {0}
    start = infos["dispatch"]["counts"]
    for a in env.agents:
        env.action_space(a).seed(6)
    total = dict.fromkeys(start, 0)
    for _ in range(120):
        _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
        for k, v in infos["workforce"]["step_counts"].items():
            total[k] += v
    assert infos["workforce"]["counts"] == {k: start[k] + total[k] for k in start}
    assert total["hires"] > 0 and total["invalid_dispatch_not_requesting"] > 0


def test_stepping_past_the_horizon_is_refused_before_the_fixed_policies_act():
    from wfbench.envs.gym_env import DispatchEnv

    env = DispatchEnv(wfbench.ScenarioConfig.preset("small").replace(horizon=4))
    env.reset(seed=1)
    truncated = False
    while not truncated:
        _, _, _, truncated, _ = env.step(np.full(env.M, env.N))
    policy = env.core.fixed["workforce"]
    calls = []
    original = policy.act
    policy.act = lambda obs: calls.append(1) or original(obs)
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(np.full(env.M, env.N))
    assert calls == [], "a refused step must not let the fixed policies act"
