"""Named scenarios as data: the paper's settings and a few of our own.

:data:`PRESET_FIELDS` holds, per preset, the :class:`wfbench.core.config.ScenarioConfig` fields
that differ from the defaults (which are ``paper-64``): ``paper-64``, the 20 ``table2-*`` cells,
``small``, ``nonstationary``, ``large``, ``city``, the ``*-64`` variants and the ``real-*``
worlds. It is plain data below the config: ``wfbench.core.config`` builds ``PRESETS`` from it,
so neither imports the other's dependants. The real-data presets read the small files under
``wfbench/core/data/`` (written by ``tools/make_real_scenarios.py``). Each preset and what it is
for: ``docs/scenarios.md``, "The presets" and "Real data".
"""

from __future__ import annotations

import csv
import io
from importlib.resources import files
from typing import Any

from wfbench.core.layout import FacilityLayout
from wfbench.core.paths import REAL_DATA
from wfbench.core.schedule import RateSchedule

TABLE2_GRIDS = (32, 64, 128, 256)
TABLE2_CELLS = ((25, 5), (25, 10), (25, 25), (50, 25), (100, 25))


def table2_name(grid: int, facilities: int, personnel: int) -> str:
    return f"table2-g{grid}-f{facilities}-s{personnel}"


REAL_SITE_JITTER = 1.0  # cells: facilities of one place spread over its neighbourhood
WEEK_HOURS = 168


def data_file(name: str) -> str:
    """The text of a committed data file under ``wfbench/core/data/``."""
    return files(REAL_DATA).joinpath(name).read_text(encoding="utf-8")


def _rows(name: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data_file(name))))


def real_sites(name: str) -> FacilityLayout:
    """The ``sites`` layout of a committed sites file: (x, y, population) per place."""
    sites = tuple((float(r["x"]), float(r["y"]), float(r["population"])) for r in _rows(name))
    return FacilityLayout(kind="sites", sites=sites, jitter=REAL_SITE_JITTER)


def weekly_schedule(name: str, horizon: int) -> RateSchedule:
    """A piecewise schedule of the 168 hourly multipliers of a committed file, one week over ``horizon`` steps.

    Hour ``h`` of the week starts at step ``round(h * horizon / 168)``.
    """
    values = tuple(float(r["multiplier"]) for r in _rows(name))
    if len(values) != WEEK_HOURS:
        raise ValueError(f"{name}: {len(values)} hourly multipliers; allowed: {WEEK_HOURS}, one per hour of the week")
    times = tuple(round(h * horizon / WEEK_HOURS) for h in range(WEEK_HOURS))
    return RateSchedule(kind="piecewise", times=times, values=values)


def _build() -> dict[str, dict[str, Any]]:
    presets: dict[str, dict[str, Any]] = {"paper-64": {}}
    presets["small"] = dict(
        grid_width=16, grid_height=16, max_facilities=8, max_personnel=8,
        initial_facilities=5, initial_personnel=4, horizon=200, request_interval=20.0,
        churn_interval=50.0, window=20,
    )
    presets["nonstationary"] = dict(
        request_schedule=RateSchedule(kind="drift", start=0.75, end=1.5),
        churn_schedule=RateSchedule(kind="drift", start=1.0, end=2.0),
    )
    presets["large"] = dict(
        grid_width=256, grid_height=256, max_facilities=200, max_personnel=200,
        initial_facilities=100, initial_personnel=100, speed=4.0,
    )
    for grid in TABLE2_GRIDS:
        for f, s in TABLE2_CELLS:
            presets[table2_name(grid, f, s)] = dict(
                grid_width=grid, grid_height=grid, initial_facilities=f,
                initial_personnel=s, max_facilities=max(50, 2 * f), max_personnel=max(50, 2 * s),
            )
    presets["surge-64"] = dict(request_schedule=RateSchedule(kind="piecewise", times=(0, 300, 500),
                                                             values=(1.0, 3.0, 1.0)))
    presets["clustered-64"] = dict(layout=FacilityLayout(kind="clustered", towns=4, spread=4.0))
    presets["slow-64"] = dict(speed=0.5)
    presets["churn-64"] = dict(churn_interval=25.0)
    presets["novice-64"] = dict(level_probs=(0.6, 0.3, 0.1))
    presets["city"] = dict(
        grid_width=576, grid_height=576, max_facilities=1000, max_personnel=1000,
        initial_facilities=500, initial_personnel=500, speed=9.0,
    )
    presets["real-benelux"] = dict(layout=real_sites("real-benelux-sites.csv"))
    presets["real-nyc"] = dict(layout=real_sites("real-nyc-sites.csv"),
                               request_schedule=weekly_schedule("nyc-departures-by-hour-of-week.csv", 800))
    return presets


PRESET_FIELDS: dict[str, dict[str, Any]] = _build()
