"""A user's own sites and request log as a scenario (wfbench/scenarios/importer.py, `wfbench scenarios import`).

The failure tests check what the user sees: one line on stderr naming the file, line and
column and what is allowed, exit status 2, and no output file (nor a temporary one) left.
"""

import subprocess
import sys

import numpy as np
import pytest

import wfbench
from wfbench import ScenarioConfig
from wfbench.cli import main
from wfbench.scenarios.importer import ScenarioFileError, from_files

SITES_XY = "id,x,y,weight\nA,10,20,3\nB,50,40,1\nC,0,63,0\n"
SITES_LATLON = "id,name,lat,lon\nams,Amsterdam,52.37,4.89\nrtm,Rotterdam,51.92,4.48\nantw,Antwerp,51.22,4.40\n"


def _write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def _log(times, sites):
    return "time,site\n" + "".join(f"{t},{s}\n" for t, s in zip(times, sites, strict=True))


def test_import__xy_sites_become_the_layout_and_the_rest_is_the_base(tmp_path):
    sites = _write(tmp_path, "s.csv", SITES_XY)
    config = from_files(sites, name="depots", base="paper-64")
    assert config.layout.kind == "sites" and config.layout.sites == ((10, 20, 3), (50, 40, 1), (0, 63, 0))
    assert config.replace(name="paper-64", layout={"kind": "uniform"}) == ScenarioConfig.preset("paper-64")
    no_weight = _write(tmp_path, "n.csv", "id,x,y\nA,1,2\nB,3,4\n")
    assert [s[2] for s in from_files(no_weight, name="n").layout.sites] == [1.0, 1.0], "weight defaults to 1"


def test_import__lat_lon_sites_are_projected_onto_the_grid_north_up(tmp_path):
    config = from_files(_write(tmp_path, "s.csv", SITES_LATLON), name="benelux3", jitter=1.5)
    (ax, ay, _), (rx, ry, _), (nx, ny, _) = config.layout.sites
    assert ay > ry > ny, "Amsterdam north of Rotterdam north of Antwerp"
    assert all(2 <= v <= 61 for s in config.layout.sites for v in s[:2]), "inside the grid's 2-cell margin"
    assert config.layout.jitter == 1.5


def test_import__a_timestamped_log_is_fitted_to_weights_rate_and_time_profile(tmp_path):
    sites = _write(tmp_path, "s.csv", SITES_XY)
    # a week; site A three times as busy as B, C never; twice as many requests in the second half
    rng = np.random.default_rng(0)
    first = rng.uniform(0, 3.5 * 86400, 160)
    second = rng.uniform(3.5 * 86400, 7 * 86400, 320)
    seconds = np.sort(np.concatenate([first, second]))
    stamps = [np.datetime_as_string(np.datetime64("2024-03-04T00:00:00") + np.timedelta64(int(s), "s"))
              for s in seconds]
    names = ["A" if i % 4 else "B" for i in range(len(stamps))]
    config = from_files(sites, _write(tmp_path, "log.csv", _log(stamps, names)), name="fitted")
    weights = {round(x): w for x, _, w in config.layout.sites}
    assert weights == {10: names.count("A"), 50: names.count("B"), 0: 0.0}, "a site's weight is its request count"
    assert config.request_interval == pytest.approx(25 * 800 / 480), "initial_facilities * horizon / requests"
    m = config.request_schedule.multipliers(800)[:800]
    assert config.request_schedule.kind == "piecewise" and abs(m.mean() - 1) < 0.02
    assert 1.7 < m[400:].mean() / m[:400].mean() < 2.3, "the second half of the log is twice as busy"


def test_import__a_log_of_steps_keeps_its_steps_and_a_short_log_a_constant_rate(tmp_path):
    sites = _write(tmp_path, "s.csv", SITES_XY)
    steps = list(range(0, 800, 2))  # 400 requests, even over the episode
    config = from_files(sites, _write(tmp_path, "log.csv", _log(steps, ["A"] * 400)), name="steps")
    assert config.request_interval == pytest.approx(50.0)
    assert np.allclose(config.request_schedule.values, 1.0, atol=0.1)
    short = from_files(sites, _write(tmp_path, "short.csv", _log([3, 9, 700], ["A", "B", "B"])), name="short")
    assert short.request_schedule.kind == "constant", "too few requests to fit a time profile"


def test_import__the_command_writes_a_scenario_that_evaluates(tmp_path, capsys):
    sites = _write(tmp_path, "s.csv", "id,x,y\nA,2,3\nB,12,13\n")
    log = _write(tmp_path, "log.csv", _log(range(0, 200, 4), ["A", "B"] * 25))
    out = tmp_path / "mine.toml"
    assert main(["scenario", "import", "--sites", str(sites), "--requests", str(log), "--name", "mine",
                 "--out", str(out), "--base", "small"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    config = ScenarioConfig.load(out)
    assert config == from_files(sites, log, name="mine", base="small")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "mine.toml", "s.csv"], "no temporary file left"
    df = wfbench.evaluate("heuristic", str(out), seeds=2)
    assert len(df) == 2 and df["nsw"].between(0, 1).all()
    json_out = tmp_path / "mine.json"
    assert main(["scenarios", "import", "--sites", str(sites), "--name", "mine", "--out", str(json_out)]) == 0
    assert ScenarioConfig.load(json_out).layout.sites == ((2, 3, 1), (12, 13, 1))


BAD_SITES = [
    ("", "line 1: the file is empty; allowed: a header naming id, x and y"),
    ("id,x,y\n", "line 2: no data after the header; allowed: one line per site after the header"),
    ("name,x,y\nA,1,2\n", "line 1: no column 'id' in the header; allowed: a header naming id"),
    ("id,x\nA,1\n", "line 1: no column 'y' in the header"),
    ("id,lat\nA,1\n", "line 1: no column 'lon' in the header"),
    ("id,x,y,lat,lon\nA,1,2,3,4\n", "line 1: both x, y and lat, lon in the header; allowed: one pair"),
    ("id,x,y\nA,1,2\nB,one,2\n", "line 3, column 'x': 'one' is not allowed; allowed: a grid column in [0, 63]"),
    ("id,x,y\nA,1,64\n", "line 2, column 'y': '64' is not allowed; allowed: a grid row in [0, 63]"),
    ("id,lat,lon\nA,95,4\n", "line 2, column 'lat': '95' is not allowed; allowed: a latitude in degrees, in [-90, 90]"),
    ("id,lat,lon\nA,50,-181\n", "line 2, column 'lon': '-181' is not allowed; allowed: a longitude in degrees"),
    ("id,x,y,weight\nA,1,2,1\nB,3,4,-2\n",
     "line 3, column 'weight': '-2' is not allowed; allowed: a finite number >= 0"),
    ("id,x,y,weight\nA,1,2,nan\n", "line 2, column 'weight': 'nan' is not allowed"),
    ("id,x,y,weight\nA,1,2,0\n", "line 2, column 'weight': every weight is 0; allowed: at least one weight > 0"),
    ("id,x,y\nA,1,2\nA,3,4\n", "line 3, column 'id': id 'A' is already on line 2; allowed: unique ids"),
    ("id,x,y\nA,1,2\nB,3\n", "line 3: 2 fields; allowed: 3 fields, one per column of the header (id, x, y)"),
    ("id,x,y\n,1,2\n", "line 2, column 'id': an empty id; allowed: a non-empty id"),
]


def _run_bad(tmp_path, capsys, argv):
    out = tmp_path / "out" / "new.toml"
    out.parent.mkdir()
    status = main([*argv, "--name", "x", "--out", str(out)])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and "Traceback" not in err, f"not one line: {err!r}"
    assert list(out.parent.iterdir()) == [], "a failed import wrote a file"
    return err


@pytest.mark.parametrize("text, message", BAD_SITES)
def test_import__a_malformed_sites_file_is_one_line_naming_file_line_and_column(text, message, tmp_path, capsys):
    sites = _write(tmp_path, "sites.csv", text)
    err = _run_bad(tmp_path, capsys, ["scenario", "import", "--sites", str(sites)])
    assert err.startswith(f"wfbench: error: {sites}, ") and message in err, err


BAD_LOGS = [
    ("", "line 1: the file is empty; allowed: a header naming time (a step or an ISO 8601 timestamp) and site"),
    ("time,where\n1,A\n", "line 1: no column 'site' in the header"),
    ("time,site\n1,A\n2,Z\n", "line 3, column 'site': site 'Z' is not in the sites file; allowed: an id of the "
                              "sites file (A, B)"),
    ("time,site\nyesterday,A\n", "line 2, column 'time': 'yesterday' is not allowed; allowed: ISO 8601 timestamps "
                                 "on every line, like the first"),
    ("time,site\n5,A\n2024-01-01T10:00,B\n", "line 3, column 'time': '2024-01-01T10:00' is not allowed; allowed: "
                                             "steps on every line, like the first"),
    ("time,site\n-5,A\n", "line 2, column 'time': '-5' is not allowed"),
    ("time,site\n1,A\n800,A\n", "line 3, column 'time': step 800 is past the episode; allowed: a step in [0, 799]"),
    ("time,site\n2024-01-01T10:00,A\n2024-01-01T10:00,B\n",
     "line 3, column 'time': every request has the same time; allowed: timestamps spanning some time"),
    ("time,site\n2024-01-01T10:00,A\n2024-01-01T11:00+01:00,B\n",
     "line 3, column 'time': '2024-01-01T11:00+01:00' is not allowed; allowed: timestamps all with a time zone or "
     "all without"),
]


@pytest.mark.parametrize("text, message", BAD_LOGS)
def test_import__a_malformed_request_log_is_one_line_naming_file_line_and_column(text, message, tmp_path, capsys):
    sites = _write(tmp_path, "sites.csv", "id,x,y\nA,1,2\nB,3,4\n")
    log = _write(tmp_path, "log.csv", text)
    err = _run_bad(tmp_path, capsys, ["scenarios", "import", "--sites", str(sites), "--requests", str(log)])
    assert err.startswith(f"wfbench: error: {log}, ") and message in err, err


def test_import__missing_files_and_options_are_one_line_too(tmp_path, capsys):
    err = _run_bad(tmp_path, capsys, ["scenario", "import", "--sites", str(tmp_path / "nope.csv")])
    assert f"{tmp_path / 'nope.csv'}: the sites file does not exist" in err
    assert main(["scenario", "import", "--sites", "s.csv", "--name", "x"]) == 2
    assert "scenarios import needs --out" in capsys.readouterr().err
    assert main(["scenario", "import", "--sites", "s.csv", "--name", "x", "--out", "x.yaml"]) == 2
    assert "allowed: a file name ending in .toml or .json" in capsys.readouterr().err
    assert main(["scenarios", "paper-64", "--sites", "s.csv"]) == 2
    assert "--sites apply to 'wfbench scenarios import' only" in capsys.readouterr().err


def test_import__a_bad_file_raises_scenario_file_error_from_python(tmp_path):
    with pytest.raises(ScenarioFileError, match=r"s\.csv, line 2, column 'x'") as info:
        from_files(_write(tmp_path, "s.csv", "id,x,y\nA,-1,2\n"), name="x")
    assert (info.value.line, info.value.column) == (2, "x")


def test_import__the_real_command_prints_one_line_and_no_traceback(tmp_path):
    sites = _write(tmp_path, "sites.csv", "id,lat,lon\nA,52,4\nB,91,4\n")
    out = tmp_path / "x.toml"
    result = subprocess.run([sys.executable, "-m", "wfbench.cli", "scenario", "import", "--sites", str(sites),
                             "--name", "x", "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and not out.exists()
    assert result.stderr == (f"wfbench: error: {sites}, line 3, column 'lat': '91' is not allowed; "
                             "allowed: a latitude in degrees, in [-90, 90]\n")
