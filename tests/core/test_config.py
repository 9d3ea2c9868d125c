import pytest

from wfbench import RateSchedule, ScenarioConfig
from wfbench.core.config import PRESETS
from wfbench.core.presets import TABLE2_CELLS, TABLE2_GRIDS, table2_name


def test_table2_has_twenty_cells_with_the_papers_sizes():
    names = [table2_name(g, f, s) for g in TABLE2_GRIDS for f, s in TABLE2_CELLS]
    assert len(names) == 20 and all(n in PRESETS for n in names)
    c = PRESETS["table2-g128-f100-s25"]
    assert (c.grid_width, c.initial_facilities, c.initial_personnel) == (128, 100, 25)


def test_paper_preset_matches_the_paper():
    c = ScenarioConfig.preset("paper-64")
    assert (c.grid_width, c.max_facilities, c.max_personnel, c.initial_facilities, c.initial_personnel) == (
        64, 50, 50, 25, 25)
    assert c.fix_probabilities == pytest.approx((0.49, 0.7, 0.84))
    assert (c.request_interval, c.churn_interval, c.window, c.horizon) == (40.0, 100.0, 50, 800)


@pytest.mark.parametrize("name", ["paper-64", "nonstationary", "small", "large"])
@pytest.mark.parametrize("fmt", ["toml", "json"])
def test_round_trip(name, fmt, tmp_path):
    c = ScenarioConfig.preset(name)
    path = tmp_path / f"c.{fmt}"
    c.save(path)
    assert ScenarioConfig.load(path) == c


def test_load_reports_bad_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("grid_width = [")
    with pytest.raises(ValueError, match="not valid TOML"):
        ScenarioConfig.load(p)


def test_schedules():
    piecewise = RateSchedule(kind="piecewise", times=(0, 10), values=(1.0, 2.0))
    assert piecewise.multipliers(20)[[0, 9, 10, 20]].tolist() == [1.0, 1.0, 2.0, 2.0]
    drift = RateSchedule(kind="drift", start=1.0, end=3.0).multipliers(10)
    assert drift[0] == 1.0 and drift[-1] == 3.0
