"""Observation version 2 (wfbench.core.observation_v2, issue #32) and the environments that show it.

Version 2 gives every length in travel-time steps and the world's public parameters as a
scale-free ``context``, the units apart in ``units``. The claim it is built for: a world
whose grid side, speed and spatial spread are multiplied by k (``scaled_world``) is the
same world in other units, and shows the same version-2 observation, bit for bit when k
is a power of two, so the scale-free network reads the same tensors; the paper's
observation (version 1) and its networks see a different world. Here: that claim, the
context worked out by hand, the peers' checkers on ``wfbench/Workforce-v1`` and
``obs_version=2`` (as tests/envs/test_envs.py and tests/envs/test_rl_libraries.py run them on
version 1), the space's bounds over whole episodes, and the docs' tables against the code.
"""

import re
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env as gym_check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, state_test
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import wfbench
from wfbench import ScenarioConfig, Simulator, policies
from wfbench.core.config import PRESETS
from wfbench.core.observation_v2 import (
    CONTEXT_FEATURES,
    UNIT_FEATURES,
    V2_KEYS,
    WORLD_FEATURES,
    C,
    W,
    observe_v2,
    scaled_world,
    world_parameters,
)
from wfbench.core.observe import FAC_X, FAC_Y, PER_BUSY, PER_HOME_X, PER_HOME_Y, PER_X, PER_Y, make_obs
from wfbench.core.state import TO_FACILITY
from wfbench.envs.spaces import SHARED_KEYS, shared_spaces

ROOT = Path(__file__).resolve().parents[2]
FAC_XY, PER_XY = [FAC_X, FAC_Y], [PER_HOME_X, PER_HOME_Y, PER_X, PER_Y]
V1_KEYS = (*SHARED_KEYS, "dispatch_mask", "workforce_mask")  # what Workforce-v0 showed before version 2
SEEDS = [1, 2]


def bits(a: np.ndarray) -> tuple:
    """An array's dtype, shape and bytes: equal only when bit for bit (unlike ==, which has 0.0 == -0.0)."""
    return a.dtype, a.shape, a.tobytes()


def run_heuristic(config, seeds=SEEDS, steps=40) -> dict[str, np.ndarray]:
    """The observation (a copy) after at least ``steps`` steps of the paper's heuristics.

    They dispatch at one step in three only, so that requests pile up, and the run goes on
    until a facility waits with someone free: the scale-free network's candidate lists are
    then not empty.
    """
    sim = Simulator(config, seeds, keep_series=False, threads=1)
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset(sim.seeds)
    t = 0
    while t < steps or not (obs["requesting"].any(1) & obs["dispatchable"].any(1)).any():
        assert t < config.horizon, "no request ever waited with someone free"
        act = pol.act(obs)
        if t % 3:
            act["dispatch"] = np.full_like(act["dispatch"], sim.N)
        obs = sim.step_observe(act)[1]
        t += 1
    return {k: np.array(v, copy=True) for k, v in obs.items()}


def twin_observation(obs: dict[str, np.ndarray], config: ScenarioConfig, k: int) -> dict[str, np.ndarray]:
    """The observation the world in other units (``scaled_world(config, k)``) shows in the state of ``obs``."""
    twin = dict(obs)
    for key, cols in (("facilities", FAC_XY), ("personnel", PER_XY)):
        arr = obs[key].copy()
        arr[..., cols] *= np.float32(k)
        twin[key] = arr
    twin["world"] = Simulator(scaled_world(config, k), SEEDS, keep_series=False).world_key(obs["t"]).copy()
    return twin


# -- the world in other units -------------------------------------------------------------------------------------
@pytest.mark.parametrize("k", [2, 4])
@pytest.mark.parametrize("scenario", ["paper-64", "small"])
def test_twin_world__version_2_and_the_scalefree_inputs_are_the_same_bits(scenario, k):
    torch = pytest.importorskip("torch")
    from wfbench.policies.neural import model, scalefree

    config = wfbench.scenario(scenario)
    obs = run_heuristic(config)
    assert (obs["t"] > 0).all() and obs["facility_mask"].any() and obs["personnel_mask"].any()
    assert obs["facilities"][..., FAC_XY].any() and obs["personnel"][..., PER_XY].any(), "nothing to scale"
    twin = twin_observation(obs, config, k)
    v2, v2_twin = observe_v2(obs), observe_v2(twin)
    assert set(v2) == set(v2_twin) == {*obs, *V2_KEYS}
    for key in v2:
        if key not in ("units", "world"):
            assert bits(v2[key]) == bits(v2_twin[key]), f"{key} of the twin world at k={k} differs"
    assert bits(v2_twin["units"]) == bits(v2["units"] * np.float32(k))

    x = scalefree.featurize(scalefree.obs_to_torch(v2), k=8, pos_freqs=3)
    x_twin = scalefree.featurize(scalefree.obs_to_torch(v2_twin), k=8, pos_freqs=3)
    assert x.keys() == x_twin.keys()
    for key in x:
        assert x[key].dtype == x_twin[key].dtype and torch.equal(x[key], x_twin[key]), f"scale-free input {key}"
    assert bool(x["choose"].any()), "no facility chooses: the candidate lists were not compared"

    # the paper's observation is in cells: its networks see another world
    y = model.featurize(model.obs_to_torch(obs), 64.0)
    y_twin = model.featurize(model.obs_to_torch(twin), 64.0)
    differ = {key for key in y if not torch.equal(y[key], y_twin[key])}
    assert {"fac_xy", "per_xy", "per_home", "dist"} <= differ, differ


@pytest.mark.parametrize("k", [2, 4])
@pytest.mark.parametrize("scenario", ["paper-64", "small"])
def test_twin_world__is_what_a_simulator_at_k_runs(scenario, k):
    config = wfbench.scenario(scenario)
    twin = scaled_world(config, k)
    sim = Simulator(twin, SEEDS, keep_series=False)
    assert (sim.params.grid_w, sim.params.grid_h) == (k * config.grid_width, k * config.grid_height)
    assert sim.params.speed == k * config.speed and twin.heat_sigma == k * config.heat_sigma
    same = twin.replace(name=config.name, grid_width=config.grid_width, grid_height=config.grid_height,
                        speed=config.speed, heat_sigma=config.heat_sigma)
    assert same == config, "scaled_world changed more than the lengths and the speed"
    world, world_twin = world_parameters(config), sim.world_key(np.zeros(len(SEEDS), np.int64))[0]
    scaled = [W[n] for n in ("speed", "grid_width", "grid_height", "heat_sigma")]
    assert np.array_equal(world_twin[scaled], world[scaled] * k)
    rest = np.ones(len(WORLD_FEATURES), bool)
    rest[scaled] = False
    assert np.array_equal(world_twin[rest], world[rest])


@pytest.mark.parametrize("k", [2, 4])
@pytest.mark.parametrize("scenario", ["paper-64", "small"])
def test_twin_simulator__shows_the_same_travel_time_range(scenario, k):
    """End to end: the twin's own simulator (its own trace) places things over the same extent in travel time."""
    config = wfbench.scenario(scenario)
    obs, obs_twin = run_heuristic(config, steps=20), run_heuristic(scaled_world(config, k), steps=20)
    fac_twin = obs_twin["facilities"][..., FAC_XY][obs_twin["facility_mask"] > 0]
    assert fac_twin.max() > config.grid_width - 1, "the twin's facilities never leave the original grid"
    v2, v2_twin = observe_v2(obs), observe_v2(obs_twin)
    world_columns = list(range(C["t"]))  # the context of the world itself, before this step's counts
    assert bits(v2["context"][:, world_columns]) == bits(v2_twin["context"][:, world_columns])
    extent = v2["context"][:, [C["extent_x"], C["extent_y"]]].max()
    for v in (v2, v2_twin):
        fac = v["facilities"][..., FAC_XY][v["facility_mask"] > 0]
        per = v["personnel"][..., PER_XY][v["personnel_mask"] > 0]
        assert fac.min() >= 0 and per.min() >= 0 and max(fac.max(), per.max()) <= extent
        assert fac.max() >= extent / 2, "the facilities should spread over the grid, in both worlds"


def test_twin_world__not_a_power_of_two_is_equal_to_rounding():
    config = wfbench.scenario("small")
    obs = run_heuristic(config)
    v2, v2_twin = observe_v2(obs), observe_v2(twin_observation(obs, config, 3))
    for key in ("facilities", "personnel", "context"):
        np.testing.assert_allclose(v2_twin[key], v2[key], rtol=1e-6, err_msg=key)


def test_scaled_world__refuses_a_layout_in_cells():
    for name in ("clustered-64", "real-nyc"):
        with pytest.raises(ValueError, match=r"^scaled_world: .* layout.*allowed: .*'uniform' layout$"):
            scaled_world(PRESETS[name], 2)


# -- observe_v2 by hand -------------------------------------------------------------------------------------------
HAND = ScenarioConfig(name="hand", grid_width=12, grid_height=8, max_facilities=4, max_personnel=3,
                      initial_facilities=3, initial_personnel=2, horizon=60, request_interval=10.0,
                      churn_interval=50.0, speed=2.0, heat_sigma=3.0)


def hand_obs():
    """3 facilities (two with an open request), 2 people (the expert on its way, so busy and not free), t = 15."""
    obs = make_obs(4, 3, facilities=[(0, 0, True), (4, 6, False), (10, 2, True)],
                   people=[(1, 1, 2, 2, 0), (6, 4, 8, 4, 2)], t=15)
    obs["personnel"][0, 1, PER_BUSY] = 1.0
    obs["personnel_status"][0, 1] = TO_FACILITY
    obs["dispatchable"][0, 1] = 0
    obs["world"] = world_parameters(HAND)[None]
    return obs


def test_observe_v2__context_by_hand():
    obs = hand_obs()
    before = {k: v.copy() for k, v in obs.items()}
    v2 = observe_v2(obs)
    ctx = dict(zip(CONTEXT_FEATURES, v2["context"][0].tolist(), strict=True))
    expect = {
        "extent_x": 12 / 2, "extent_y": 8 / 2, "heat_sigma": 3 / 2,  # steps of travel at speed 2
        "horizon": 60, "window": 50, "service_time": 3, "hire_delay": 20, "notice_delay": 10,
        "request_interval": 10, "churn_interval": 50, "request_rate": 1 / 10, "churn_rate": 1 / 50,
        "fix_novice": 0.7 * 0.7, "fix_mid": 0.7, "fix_expert": 0.7 * 1.2,
        "salary_novice": 1.0, "salary_mid": 1.5, "salary_expert": 2.0,
        "target_utilization": 0.75, "utilization_tolerance": 0.05,
        "max_facilities": 4, "max_personnel": 3, "min_personnel": 1,
        "t": 15, "time_left": 45,
        "active_facilities": 3, "employed": 2, "free": 1, "busy": 1, "open_requests": 2,
        "facilities_per_person": 3 / 2, "open_per_free": 2 / 1, "load_per_person": (1 + 2) / 2,
    }
    assert ctx == pytest.approx(expect, rel=1e-6)
    assert v2["facilities"][0, :3][:, FAC_XY].tolist() == [[0, 0], [2, 3], [5, 1]]
    assert v2["personnel"][0, :2][:, PER_XY].tolist() == [[0.5, 0.5, 1, 1], [3, 2, 4, 2]]
    assert v2["units"].tolist() == [[2, 12, 8]] and v2["units"].dtype == np.float32
    assert v2["context"].dtype == np.float32 and v2["context"].shape == (1, len(CONTEXT_FEATURES)) == (1, 33)
    assert all(bits(obs[k]) == bits(before[k]) for k in obs), "observe_v2 wrote into its input"


def test_observe_v2__a_count_of_zero_divides_as_one():
    obs = make_obs(4, 3, facilities=[(1, 1, True), (2, 2, True)], t=0)
    obs["world"] = world_parameters(HAND)[None]
    ctx = observe_v2(obs)["context"][0]
    assert ctx[C["employed"]] == ctx[C["free"]] == 0
    assert (ctx[C["facilities_per_person"]], ctx[C["open_per_free"]], ctx[C["load_per_person"]]) == (2, 2, 2)


def test_observe_v2__each_row_in_its_own_world():
    a, b = hand_obs(), hand_obs()
    b["world"] = world_parameters(HAND.replace(speed=4.0))[None]
    both = observe_v2({k: np.concatenate([a[k], b[k]]) for k in a})
    assert bits(both["facilities"][:1]) == bits(observe_v2(a)["facilities"])
    assert bits(both["facilities"][1:]) == bits(observe_v2(b)["facilities"])
    assert both["context"][:, C["extent_x"]].tolist() == [6, 3]


# -- the environments ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id, kwargs", [("wfbench/Workforce-v1", {}), ("wfbench/Dispatch-v0", {"obs_version": 2})])
@pytest.mark.parametrize("scenario", ["small", "paper-64"])
def test_gymnasium_and_sb3_checkers_on_version_2(env_id, kwargs, scenario, strict_warnings):
    env = gymnasium.make(env_id, scenario=scenario, **kwargs)
    assert env.unwrapped.obs_version == 2 and {"context", "units"} <= set(env.observation_space.spaces)
    gym_check_env(env.unwrapped)
    sb3_check_env(env.unwrapped)


def test_gymnasium_checker_on_version_2_flattened(strict_warnings):
    env = gymnasium.make("wfbench/Workforce-v1", scenario="small", observation="box")
    dict_space = env.unwrapped.dict_observation_space
    assert env.observation_space.shape == (spaces.flatdim(dict_space),)
    gym_check_env(env.unwrapped)


@pytest.mark.parametrize("scenario", ["small", "paper-64"])
def test_parallel_api_on_version_2(scenario, strict_warnings):
    parallel_api_test(wfbench.parallel_env(scenario, obs_version=2), num_cycles=100)


@pytest.mark.parametrize("fixed", [None, {"workforce": "threshold", "positioning": "heuristic"}])
def test_parallel_seed_on_version_2(fixed, strict_warnings):
    parallel_seed_test(lambda: wfbench.parallel_env("small", fixed=fixed, obs_version=2))


def test_aec_api_and_state_on_version_2(strict_warnings):
    api_test(wfbench.env("small", obs_version=2), num_cycles=100)
    state_test(wfbench.env("small", obs_version=2), wfbench.parallel_env("small", obs_version=2))
    env = wfbench.parallel_env("small", obs_version=2)
    env.reset(seed=0)
    assert env.state_space.contains(env.state()) and env.metadata["name"] == "wfbench_workforce_v1"
    assert wfbench.parallel_env("small").metadata["name"] == "wfbench_workforce_v0"


def test_library_options_on_version_2(strict_warnings):
    options = {"observation": "box", "actions": "shared", "obs_version": 2}
    parallel_api_test(wfbench.parallel_env("small", **options), num_cycles=50)
    parallel_seed_test(lambda: wfbench.parallel_env("small", **options))


def test_make_vec_of_workforce_v1_replays_the_single_envs():
    """The vector entry point and SyncVectorEnv of the single env both get obs_version=2 from the id."""
    batched = gymnasium.make_vec("wfbench/Workforce-v1", num_envs=2, scenario="small")
    sync = gymnasium.make_vec("wfbench/Workforce-v1", num_envs=2, scenario="small", vectorization_mode="sync")
    assert batched.unwrapped.obs_version == 2 and batched.single_observation_space == sync.single_observation_space
    a, _ = batched.reset(seed=4)
    b, _ = sync.reset(seed=4)
    batched.action_space.seed(4)
    for _ in range(25):
        assert a.keys() == b.keys() and all(bits(a[k]) == bits(b[k]) for k in a)
        assert batched.observation_space.contains(a)
        act = batched.action_space.sample()
        a, *_ = batched.step(act)
        b, *_ = sync.step(act)


def test_workforce_v1_is_workforce_v0_in_travel_time():
    """The same episode through both ids: v0 shows what it showed before, v1 is observe_v2 of it, in its space."""
    config = wfbench.scenario("small").replace(speed=1.5, horizon=120)
    v0 = gymnasium.make("wfbench/Workforce-v0", scenario=config).unwrapped
    v1 = gymnasium.make("wfbench/Workforce-v1", scenario=config).unwrapped
    assert (v0.obs_version, v1.obs_version) == (1, 2)
    assert v1.observation_space.spaces.keys() == {*V1_KEYS, *V2_KEYS}
    assert v0.observation_space.spaces.keys() == set(V1_KEYS), "Workforce-v0's space changed its keys"
    o0, _ = v0.reset(seed=3)
    o1, _ = v1.reset(seed=3)
    v0.action_space.seed(3)
    done = False
    while not done:
        assert tuple(o0) == V1_KEYS, "Workforce-v0's observation keys changed"
        assert tuple(o1) == (*SHARED_KEYS, *V2_KEYS, "dispatch_mask", "workforce_mask")
        assert v1.observation_space.contains(o1), [k for k in o1 if not v1.observation_space[k].contains(o1[k])]
        for k in V1_KEYS:
            if k not in ("facilities", "personnel"):
                assert bits(o1[k]) == bits(o0[k]), k
        expect = observe_v2({**{k: v[None] for k, v in o0.items()}, "t": v0.core.obs["t"],
                             "world": v0.core.obs["world"]})
        for k in ("facilities", "personnel", "context", "units"):
            assert bits(o1[k]) == bits(expect[k][0]), k
        act = v0.action_space.sample()
        o0, r0, _, done, _ = v0.step(act)
        o1, r1, _, done1, _ = v1.step(act)
        assert r0 == r1 and done == done1


@pytest.mark.parametrize("scenario", ["small", "nonstationary", "surge-64", "churn-64"])
def test_version_2_bounds_hold_over_a_whole_episode(scenario):
    """The heuristics through a whole episode (hiring, letting go, schedules): every row in the space."""
    config = wfbench.scenario(scenario)
    space = spaces.Dict(shared_spaces(config, 2))
    sim = Simulator(config, SEEDS, keep_series=False, threads=1)
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset(sim.seeds)
    seen = np.zeros((len(SEEDS), len(CONTEXT_FEATURES)), np.float32)
    while True:
        v2 = observe_v2(obs)
        for b in range(sim.B):
            row = {k: v2[k][b] for k in space.spaces}
            assert space.contains(row), (sim.state.t[b], [k for k in row if not space[k].contains(row[k])])
        seen = np.maximum(seen, v2["context"])
        if sim.done:
            break
        obs = sim.step_observe(pol.act(obs))[1]
    high = space["context"].high
    for name in ("request_rate", "churn_rate", "t", "time_left"):
        assert seen[:, C[name]].max() == high[C[name]], f"{name} never reaches its bound: the bound is loose"


@pytest.mark.parametrize("scenario", sorted(PRESETS))
def test_version_2_space_of_every_preset_is_finite_and_holds_its_first_steps(scenario):
    config = PRESETS[scenario]
    space = spaces.Dict(shared_spaces(config, 2))
    for key in ("facilities", "personnel", "context", "units"):
        box = space[key]
        assert np.isfinite(box.low).all() and np.isfinite(box.high).all() and (box.low < box.high).all(), key
    sim = Simulator(config, [0], keep_series=False, threads=1)
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset(sim.seeds)
    for _ in range(5):
        v2 = observe_v2(obs)
        row = {k: v2[k][0] for k in space.spaces}
        assert space.contains(row), [k for k in row if not space[k].contains(row[k])]
        obs = sim.step_observe(pol.act(obs))[1]


@pytest.mark.slow
def test_sb3_policy_of_a_version_2_model_reads_version_2():
    pytest.importorskip("torch")
    from stable_baselines3 import PPO

    from wfbench.envs.sb3 import EntitySetExtractor, SB3Policy, WorkforceVecEnv

    venv = WorkforceVecEnv("small", num_envs=2, obs_version=2, seed=0)
    assert {"context", "units"} <= set(venv.observation_space.spaces)
    model = PPO("MultiInputPolicy", venv, n_steps=8, batch_size=8,
                policy_kwargs={"features_extractor_class": EntitySetExtractor}, device="cpu", seed=0)
    pol = SB3Policy(model, "small")
    assert pol.observation_version == 2
    sim = Simulator(wfbench.scenario("small"), SEEDS, keep_series=False)
    obs = sim.reset()
    pol.reset(sim.seeds)
    for _ in range(3):
        obs = sim.step_observe(pol.act(obs))[1]


# -- a bad version ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [3, 0, True, 2.0, "2", None])
def test_bad_obs_version_is_one_line_naming_what_is_allowed(bad):
    message = f"obs_version={bad!r} is not allowed; allowed: 1, 2"
    makers = [lambda: gymnasium.make("wfbench/Workforce-v1", scenario="small", obs_version=bad),
              lambda: gymnasium.make("wfbench/Dispatch-v0", scenario="small", obs_version=bad),
              lambda: gymnasium.make_vec("wfbench/Workforce-v0", 2, scenario="small", obs_version=bad),
              lambda: wfbench.parallel_env("small", obs_version=bad),
              lambda: wfbench.env("small", obs_version=bad)]
    for make in makers:
        with pytest.raises(ValueError) as err:
            make()
        assert str(err.value) == message


# -- the docs ------------------------------------------------------------------------------------------------------
def doc_table(heading: str) -> list[str]:
    """The names (second column) of the table under ``heading`` in docs/policies.md, in order."""
    text = (ROOT / "docs" / "policies.md").read_text()
    start = text.index(heading + "\n")
    rows = []
    for line in text[start:].splitlines()[1:]:
        if rows and not line.startswith("|"):
            break
        m = re.match(r"^\| *(\d+) *\| *`([a-z_]+)`", line)
        if m:
            assert int(m.group(1)) == len(rows), f"{heading}: column {m.group(1)} out of order"
            rows.append(m.group(2))
    return rows


def test_docs_list_every_column_in_order():
    """docs/policies.md, "Observation version 2": one row per column of world, context and units, as the code."""
    assert doc_table("#### The `world` columns") == list(WORLD_FEATURES)
    assert doc_table("#### The `context` columns") == list(CONTEXT_FEATURES)
    assert doc_table("#### The `units` columns") == list(UNIT_FEATURES)
