"""Facility layouts (wfbench/core/layout.py) and the synthetic presets of the suite (docs/scenarios.md).

The layouts act only through the trace, so these tests read the trace's cells; the
tolerances of the statistical ones are several standard deviations on fixed seeds.
"""

import hashlib

import numpy as np
import pytest

import wfbench
from wfbench import ScenarioConfig, trace
from wfbench.core.config import PRESETS
from wfbench.core.layout import FacilityLayout

# sha256 of to_json() of presets that existed before layouts, recorded before the field was added:
# the leaderboard hashes to_dict(), so a new field at its default must not show in it
HASH_BEFORE_LAYOUTS = {
    "paper-64": "c9667334912f6d80", "small": "dea0c8ef37f12965", "large": "be6f48e9fbae957a",
    "nonstationary": "e847a4261ba1029c", "table2-g128-f50-s25": "060d7f0919b27b31",
}


def _cells(t):
    return (np.concatenate([t.fac0_x[0], t.arr_x[0]]), np.concatenate([t.fac0_y[0], t.arr_y[0]]))


@pytest.mark.parametrize("name", sorted(HASH_BEFORE_LAYOUTS))
def test_layouts__a_scenario_at_the_default_layout_keeps_its_dict_and_hash(name):
    config = ScenarioConfig.preset(name)
    assert "layout" not in config.to_dict(), f"{name}: to_dict() writes the default layout"
    assert hashlib.sha256(config.to_json().encode()).hexdigest()[:16] == HASH_BEFORE_LAYOUTS[name], (
        f"{name}: to_json() changed, so every leaderboard hash of it would")
    assert config.replace(layout=FacilityLayout()) == config
    assert config.replace(layout={"kind": "uniform"}) == config


@pytest.mark.parametrize("layout", [
    FacilityLayout(kind="clustered", towns=3, spread=2.5),
    FacilityLayout(kind="sites", sites=((1, 2, 3.0), (60.5, 60, 1)), jitter=0.5),
])
@pytest.mark.parametrize("fmt", ["toml", "json"])
def test_layouts__a_layout_survives_the_file_round_trip(layout, fmt, tmp_path):
    config = ScenarioConfig(name="x", layout=layout)
    path = tmp_path / f"c.{fmt}"
    config.save(path)
    assert ScenarioConfig.load(path) == config
    assert config.to_dict()["layout"]["kind"] == layout.kind


def test_layouts__a_layout_changes_only_the_facility_cells():
    uniform = ScenarioConfig.preset("paper-64")
    clustered = ScenarioConfig.preset("clustered-64")
    for seed in range(3):
        a, b = trace(uniform, seed), trace(clustered, seed)
        for name in a._fields:
            same = np.array_equal(getattr(a, name), getattr(b, name))
            assert same == (name not in ("fac0_x", "fac0_y", "arr_x", "arr_y")), (
                f"seed {seed}: trace.{name} {'equal' if same else 'differs'} between the uniform and clustered layouts")


def test_layouts__clustered_facilities_lie_around_a_town_that_moves_with_the_seed():
    config = ScenarioConfig(name="one-town", layout=FacilityLayout(kind="clustered", towns=1, spread=2.0),
                            churn_interval=20.0)
    centres = []
    for seed in range(4):
        x, y = _cells(trace(config, seed))
        assert len(x) > 50
        # normal offsets of sd 2 per axis: every cell within 5 sd of the cloud's mean
        assert np.abs(x - x.mean()).max() <= 10 and np.abs(y - y.mean()).max() <= 10, (
            f"seed {seed}: facility cells spread over x {x.min()}..{x.max()}, y {y.min()}..{y.max()} "
            "for one town of spread 2")
        assert abs(x.std() - 2.0) < 0.6 and abs(y.std() - 2.0) < 0.6, f"seed {seed}: sd {x.std():.2f}, {y.std():.2f}"
        centres.append((round(x.mean()), round(y.mean())))
    assert len(set(centres)) == 4, f"town centres {centres}: the towns should be drawn anew for each seed"
    assert trace(config, 2).fac0_x.tolist() == trace(config, 2).fac0_x.tolist()


def test_layouts__clustered_initial_cells_do_not_depend_on_the_arrivals():
    base = ScenarioConfig.preset("clustered-64")
    more = base.replace(churn_interval=10.0)
    a, b = trace(base, 7), trace(more, 7)
    assert a.arr_x.shape[1] < b.arr_x.shape[1]
    assert np.array_equal(a.fac0_x, b.fac0_x) and np.array_equal(a.fac0_y, b.fac0_y)


def test_layouts__sites_are_picked_in_proportion_to_their_weight():
    sites = ((3, 4, 3.0), (50, 60, 1.0), (20, 20, 0.0))
    config = ScenarioConfig(name="sites", layout=FacilityLayout(kind="sites", sites=sites), churn_interval=10.0)
    xs, ys = zip(*(_cells(trace(config, s)) for s in range(10)), strict=True)
    x, y = np.concatenate(xs), np.concatenate(ys)
    cells = set(zip(x.tolist(), y.tolist(), strict=True))
    assert cells == {(3, 4), (50, 60)}, f"cells {cells}: without jitter every facility is on a site of weight > 0"
    share = np.mean(x == 3)
    se = (0.75 * 0.25 / len(x)) ** 0.5
    assert abs(share - 0.75) < 5 * se, f"share of the weight-3 site {share:.3f} over {len(x)}, expected 0.75"


def test_layouts__jittered_sites_stay_on_the_grid():
    config = ScenarioConfig(name="edge", grid_width=10, grid_height=8, layout=FacilityLayout(
        kind="sites", sites=((0, 0, 1.0), (9, 7, 1.0)), jitter=3.0), churn_interval=10.0)
    x, y = _cells(trace(config, 0))
    assert x.min() >= 0 and x.max() <= 9 and y.min() >= 0 and y.max() <= 7
    assert len(set(zip(x.tolist(), y.tolist(), strict=True))) > 2, "jitter 3 should spread facilities off the sites"


@pytest.mark.parametrize("layout, message", [
    (dict(kind="towns"),
     "ScenarioConfig.layout.kind = 'towns' is not allowed; allowed: 'uniform', 'clustered', 'sites'"),
    (dict(kind="clustered", towns=0), "ScenarioConfig.layout.towns = 0 is not allowed; allowed: an integer in"),
    (dict(kind="clustered", spread=-1.0), "ScenarioConfig.layout.spread = -1.0 is not allowed; allowed: a finite"),
    (dict(kind="uniform", towns=3), "ScenarioConfig.layout.towns = 3 is not allowed; allowed: its default 4: it "
                                    "applies to the clustered layout only"),
    (dict(kind="sites"), "ScenarioConfig.layout.sites = () is not allowed; allowed: at least one (x, y, weight)"),
    (dict(kind="sites", sites=[[1, 2, -1]]), r"ScenarioConfig.layout.sites[0] = (1.0, 2.0, -1.0) is not allowed; "
                                             "allowed: (x, y, weight) with finite numbers and weight >= 0"),
    (dict(kind="sites", sites=[[1, 2, 0]]), "at least one (x, y, weight) site, with weights summing to more than 0"),
    (dict(kind="sites", sites=[[1, 64, 1]]), "ScenarioConfig.layout.sites[0] = (1.0, 64.0) is not allowed; allowed: "
                                             "x in [0, 63] and y in [0, 63]"),
    (dict(kind="sites", sites=[[1, 2]]), r"ScenarioConfig.layout.sites[0] = (1.0, 2.0) is not allowed"),
    (dict(kind="sites", sites=[[1, 2, 1]], jitter=float("nan")), "ScenarioConfig.layout.jitter = nan"),
    (dict(kind="clustered", colour=1), "unknown layout field(s) ['colour']"),
])
def test_layouts__a_bad_layout_names_the_field_the_value_and_what_is_allowed(layout, message):
    with pytest.raises(ValueError) as info:
        ScenarioConfig(name="bad", layout=layout)
    assert message in str(info.value)


def test_layouts__the_synthetic_presets_are_what_the_suite_names():
    paper = PRESETS["paper-64"]
    assert PRESETS["surge-64"].request_schedule.multipliers(800)[[0, 299, 300, 499, 500, 800]].tolist() == [
        1, 1, 3, 3, 1, 1]
    assert PRESETS["clustered-64"].layout.kind == "clustered"
    assert PRESETS["slow-64"].speed == 0.5
    assert PRESETS["churn-64"].churn_interval == 25.0
    assert PRESETS["novice-64"].level_probs == (0.6, 0.3, 0.1)
    for name in ("surge-64", "clustered-64", "slow-64", "churn-64", "novice-64"):
        differ = {k for k, v in PRESETS[name].to_dict().items() if paper.to_dict().get(k) != v} - {"name"}
        assert len(differ) == 1, f"{name} differs from paper-64 in {sorted(differ)}: one change each"
    city, large = PRESETS["city"], PRESETS["large"]
    assert (city.grid_width, city.grid_height, city.speed) == (576, 576, 9.0)
    assert (city.max_facilities, city.max_personnel, city.initial_facilities, city.initial_personnel) == (
        1000, 1000, 500, 500)
    assert city.initial_facilities >= 5 * large.initial_facilities
    assert city.initial_personnel >= 5 * large.initial_personnel


def test_layouts__a_clustered_scenario_runs_end_to_end():
    config = ScenarioConfig.preset("small").replace(layout=FacilityLayout(kind="clustered", towns=2, spread=2.0))
    df = wfbench.evaluate("heuristic", config, seeds=2)
    assert len(df) == 2 and df["nsw"].between(0, 1).all()
