"""The real-data presets (docs/scenarios.md, "Real data"): their committed files, the presets built on them,
and the script that made the files (tools/make_real_scenarios.py, run on the pinned data packages).
"""

import csv
import io
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wfbench
from wfbench.core.config import PRESETS
from wfbench.core.layout import project_latlon
from wfbench.core.presets import data_file

ROOT = Path(__file__).resolve().parents[2]
SITE_FILES = {"real-benelux": "real-benelux-sites.csv", "real-nyc": "real-nyc-sites.csv"}
WEEK_FILE = "nyc-departures-by-hour-of-week.csv"


def _rows(name):
    return list(csv.DictReader(io.StringIO(data_file(name))))


def _km(a, b):
    p1, p2 = math.radians(float(a["latitude"])), math.radians(float(b["latitude"]))
    dl = math.radians(float(b["longitude"]) - float(a["longitude"]))
    h = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * 6371.0 * math.asin(math.sqrt(h))


@pytest.mark.parametrize("preset", sorted(SITE_FILES))
def test_real_scenarios__the_sites_file_parses_and_is_the_presets_layout(preset):
    rows = _rows(SITE_FILES[preset])
    assert len(rows) == 100
    for r in rows:
        assert -90 <= float(r["latitude"]) <= 90 and -180 <= float(r["longitude"]) <= 180, r
        assert int(r["population"]) > 0 and 2 <= float(r["x"]) <= 61 and 2 <= float(r["y"]) <= 61, r
    pops = [int(r["population"]) for r in rows]
    assert pops == sorted(pops, reverse=True), "sites are the largest places, largest first"
    config = PRESETS[preset]
    assert config.layout.kind == "sites" and config.layout.jitter == 1.0
    assert config.layout.sites == tuple((float(r["x"]), float(r["y"]), float(r["population"])) for r in rows)
    assert config.replace(layout=wfbench.ScenarioConfig().layout) == PRESETS["paper-64"].replace(
        name=preset, request_schedule=config.request_schedule), f"{preset}: paper-64 apart from its data"


def test_real_scenarios__the_places_are_where_the_map_has_them():
    benelux = {r["name"]: r for r in _rows(SITE_FILES["real-benelux"])}
    nyc = {r["name"]: r for r in _rows(SITE_FILES["real-nyc"])}
    assert {"Amsterdam", "Rotterdam", "Antwerp", "Luxembourg"} <= set(benelux)
    assert {"Newark", "Jersey City", "Yonkers", "Upper West Side"} <= set(nyc)
    # the aggregates geonames lists beside their parts are dropped
    assert "Brussels" not in benelux and not {"New York City", "Brooklyn", "Manhattan"} & set(nyc)
    assert float(benelux["Amsterdam"]["y"]) > float(benelux["Antwerp"]["y"]), "north is up"
    assert float(nyc["Newark"]["x"]) < float(nyc["Jersey City"]["x"]), "east is right"
    # one scale on both axes: cells per km the same for every pair, to the projection's few percent
    for rows in (benelux, nyc):
        names = sorted(rows)[:12]
        cell = {n: (float(rows[n]["x"]), float(rows[n]["y"])) for n in names}
        ratios = [math.dist(cell[a], cell[b]) / _km(rows[a], rows[b])
                  for i, a in enumerate(names) for b in names[i + 1:] if _km(rows[a], rows[b]) > 5]
        assert max(ratios) / min(ratios) < 1.05, f"cells per km from {min(ratios):.4f} to {max(ratios):.4f}"


def test_real_scenarios__real_nyc_follows_a_week_of_departures_over_its_800_steps():
    rows = _rows(WEEK_FILE)
    assert [int(r["hour_of_week"]) for r in rows] == list(range(168))
    mult = np.array([float(r["multiplier"]) for r in rows])
    assert (mult > 0).all() and abs(mult.mean() - 1) < 1e-5
    schedule = PRESETS["real-nyc"].request_schedule
    assert schedule.kind == "piecewise" and schedule.values == tuple(mult)
    assert schedule.times[0] == 0 and schedule.times[-1] == round(167 * 800 / 168)
    m = schedule.multipliers(800)
    monday_3am, monday_8am = m[round(3 * 800 / 168)], m[round(8 * 800 / 168)]
    assert monday_8am > 1 > 0.1 > monday_3am, f"Monday 08:00 {monday_8am:.2f}, 03:00 {monday_3am:.2f}"
    assert abs(m[:800].mean() - 1) < 0.02, "the week's mean failure rate stays paper-64's"


def test_real_scenarios__both_presets_evaluate():
    for name in ("real-benelux", "real-nyc"):
        df = wfbench.evaluate("heuristic", name, seeds=1)
        assert df["nsw"].between(0.3, 1).all(), f"{name}: nsw {df['nsw'].tolist()}"


def test_real_scenarios__projection_fits_the_grid_with_its_margin():
    x, y = project_latlon([50.0, 52.0, 51.0], [3.0, 6.0, 4.0], 64, 32, margin=2.0)
    assert x.min() >= 2 - 1e-9 and x.max() <= 61 + 1e-9 and y.min() >= 2 - 1e-9 and y.max() <= 29 + 1e-9
    assert math.isclose(y.max() - y.min(), 27) or math.isclose(x.max() - x.min(), 59)
    assert project_latlon([40.0], [-74.0], 64, 64) == (np.array([31.5]), np.array([31.5]))


@pytest.mark.slow
def test_real_scenarios__the_script_regenerates_the_committed_files(tmp_path):
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "make_real_scenarios.py"), "--out",
                             str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    for name in (*SITE_FILES.values(), WEEK_FILE):
        assert (tmp_path / name).read_text(encoding="utf-8") == data_file(name), (
            f"{name}: the script no longer writes the committed file")
