"""Named scenarios as data: the paper's settings and a few of our own.

Each preset is the set of :class:`wfbench.core.config.ScenarioConfig` fields that differ
from the defaults (the defaults are ``paper-64``). This module is plain data below the
config: ``wfbench.core.config`` builds ``PRESETS`` (name -> config) from ``PRESET_FIELDS``,
so neither module imports the other's dependants (``docs/design.md``, layers).

- ``paper-64``: the paper's 'Quantitative comparison' setting (64x64, 50 facility and
  50 personnel slots, 25 of each at start, 800 steps).
- ``table2-g{32,64,128,256}-f{F}-s{S}``: the 20 cells of the paper's Table 2
  (25F x 5S, 25F x 10S, 25F x 25S, 50F x 25S, 100F x 25S on each grid).
- ``small``: a tiny world for tests and quick experiments.
- ``nonstationary``: ``paper-64`` with failure and churn rates drifting upward.
- ``large``: 256x256, 200 facility and 200 personnel slots.
"""

from __future__ import annotations

from typing import Any

from wfbench.core.schedule import RateSchedule

TABLE2_GRIDS = (32, 64, 128, 256)
TABLE2_CELLS = ((25, 5), (25, 10), (25, 25), (50, 25), (100, 25))


def table2_name(grid: int, facilities: int, personnel: int) -> str:
    return f"table2-g{grid}-f{facilities}-s{personnel}"


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
    return presets


PRESET_FIELDS: dict[str, dict[str, Any]] = _build()
