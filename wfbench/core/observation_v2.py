"""Observation version 2: the world in travel time, with its public parameters as context.

Version 1 (:mod:`wfbench.core.observe`, the paper's) stays as it is, to the bit. Version 2 is
derived from it and from the ``world`` key (:data:`WORLD_FEATURES`) every observation carries:
every length in travel-time steps, the public parameters and ratio-keeping counts as ``context``
(:data:`CONTEXT_FEATURES`), and the grid-cell quantities apart under ``units``. A world scaled
by k gives the same observation except ``units`` and ``world`` (bit for bit when k is a power of
two; ``tests/core/test_observe_v2.py``). A policy calls :func:`observe_v2` itself; the
environments take ``obs_version=2``. The keys: ``docs/policies.md``, "Observation version 2".
"""

from __future__ import annotations

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.observe import (
    FAC_X,
    FAC_Y,
    PER_BUSY,
    PER_HOME_X,
    PER_HOME_Y,
    PER_X,
    PER_Y,
)

OBS_VERSIONS = (1, 2)

# the public parameters of the world, in its own units (the key "world" of every observation)
WORLD_FEATURES = (
    "speed", "grid_width", "grid_height", "heat_sigma",  # cells per step, cells, cells, cells
    "horizon", "window", "service_time", "hire_delay", "notice_delay",  # steps
    "request_interval", "churn_interval",  # mean steps between failures of a facility, between new facilities
    "request_multiplier", "churn_multiplier",  # the rate schedules' multipliers at this step
    "fix_novice", "fix_mid", "fix_expert",  # probability that one visit fixes the facility, per level
    "salary_novice", "salary_mid", "salary_expert",  # per step
    "target_utilization", "utilization_tolerance",
    "max_facilities", "max_personnel", "min_personnel",  # slots and the smallest retained headcount
)
W = {name: i for i, name in enumerate(WORLD_FEATURES)}
# which entries of "world" change from step to step (the rest is fixed per world)
WORLD_DYNAMIC = ("request_multiplier", "churn_multiplier")

# the context of version 2: scale-free (steps, probabilities, salaries, counts and their ratios)
CONTEXT_FEATURES = (
    # the world, in travel time
    "extent_x", "extent_y", "heat_sigma",  # steps of travel across the grid; width of the heat map's bumps
    "horizon", "window", "service_time", "hire_delay", "notice_delay",  # steps
    "request_interval", "churn_interval",  # steps
    "request_rate", "churn_rate",  # per step now: failures per facility, new facilities
    "fix_novice", "fix_mid", "fix_expert",
    "salary_novice", "salary_mid", "salary_expert",
    "target_utilization", "utilization_tolerance",
    "max_facilities", "max_personnel", "min_personnel",
    # this step
    "t", "time_left",  # steps
    "active_facilities", "employed", "free", "busy", "open_requests",  # counts
    "facilities_per_person", "open_per_free", "load_per_person",  # ratios (a count of 0 counts as 1 below)
)
C = {name: i for i, name in enumerate(CONTEXT_FEATURES)}
UNIT_FEATURES = ("speed", "grid_width", "grid_height")
# the observation's keys in version 2 beyond version 1's
V2_KEYS = ("context", "units")


def world_parameters(config: ScenarioConfig) -> np.ndarray:
    """The fixed part of :data:`WORLD_FEATURES` of ``config`` (the dynamic entries hold 1.0), float64."""
    c = config
    values = {
        "speed": c.speed, "grid_width": c.grid_width, "grid_height": c.grid_height, "heat_sigma": c.heat_sigma,
        "horizon": c.horizon, "window": c.window, "service_time": c.service_time, "hire_delay": c.hire_delay,
        "notice_delay": c.fire_delay, "request_interval": c.request_interval, "churn_interval": c.churn_interval,
        "request_multiplier": 1.0, "churn_multiplier": 1.0,
        **dict(zip(("fix_novice", "fix_mid", "fix_expert"), c.fix_probabilities, strict=True)),
        **dict(zip(("salary_novice", "salary_mid", "salary_expert"), c.level_salaries, strict=True)),
        "target_utilization": c.target_utilization, "utilization_tolerance": c.utilization_tolerance,
        "max_facilities": c.max_facilities, "max_personnel": c.max_personnel, "min_personnel": c.min_personnel,
    }
    return np.array([float(values[name]) for name in WORLD_FEATURES], dtype=np.float64)


class WorldKey:
    """Fills the ``world`` key of a simulator's observations: the fixed parameters and this step's multipliers."""

    def __init__(self, config: ScenarioConfig, B: int):
        self.fixed = world_parameters(config)
        self.request = config.request_schedule.multipliers(config.horizon)  # (horizon + 1,)
        self.churn = config.churn_schedule.multipliers(config.horizon)
        self.buffer = np.tile(self.fixed, (B, 1))
        # constant schedules (most worlds): the multipliers stay 1, nothing to write per step
        self.constant = bool((self.request == 1.0).all() and (self.churn == 1.0).all())

    def __call__(self, t: np.ndarray) -> np.ndarray:
        if self.constant:
            return self.buffer
        tt = np.minimum(t, len(self.request) - 1)
        self.buffer[:, W["request_multiplier"]] = self.request[tt]
        self.buffer[:, W["churn_multiplier"]] = self.churn[tt]
        return self.buffer


def _safe(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 1.0)


def observe_v2(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The version-2 observation of a (batched, leading axis B) version-1 observation with its ``world`` key.

    A new dict: the coordinates in ``facilities`` and ``personnel`` in travel-time
    steps, ``context`` (B, len(CONTEXT_FEATURES)) and ``units`` (B, 3) added, every other
    key shared with ``obs`` (not copied). The arithmetic is in float64, rounded once to
    float32, so a world in other units by a power of two gives the same bits.
    """
    world = np.asarray(obs["world"], dtype=np.float64)
    speed = world[:, W["speed"]]
    fac = obs["facilities"].astype(np.float64)
    per = obs["personnel"].astype(np.float64)
    inv = speed[:, None]
    fac[..., FAC_X] /= inv
    fac[..., FAC_Y] /= inv
    for col in (PER_HOME_X, PER_HOME_Y, PER_X, PER_Y):
        per[..., col] /= inv
    fac_mask = obs["facility_mask"].astype(bool)
    per_mask = obs["personnel_mask"].astype(bool)
    active = fac_mask.sum(-1).astype(np.float64)
    employed = per_mask.sum(-1).astype(np.float64)
    free = obs["dispatchable"].astype(bool).sum(-1).astype(np.float64)
    busy = ((per[..., PER_BUSY] > 0) & per_mask).sum(-1).astype(np.float64)
    open_requests = obs["requesting"].astype(bool).sum(-1).astype(np.float64)
    t = np.asarray(obs["t"], dtype=np.float64)
    ctx = np.empty((len(t), len(CONTEXT_FEATURES)), dtype=np.float64)
    ctx[:, C["extent_x"]] = world[:, W["grid_width"]] / speed
    ctx[:, C["extent_y"]] = world[:, W["grid_height"]] / speed
    ctx[:, C["heat_sigma"]] = world[:, W["heat_sigma"]] / speed
    for name in ("horizon", "window", "service_time", "hire_delay", "notice_delay", "request_interval",
                 "churn_interval", "fix_novice", "fix_mid", "fix_expert", "salary_novice", "salary_mid",
                 "salary_expert", "target_utilization", "utilization_tolerance", "max_facilities", "max_personnel",
                 "min_personnel"):
        ctx[:, C[name]] = world[:, W[name]]
    ctx[:, C["request_rate"]] = world[:, W["request_multiplier"]] / world[:, W["request_interval"]]
    ctx[:, C["churn_rate"]] = world[:, W["churn_multiplier"]] / world[:, W["churn_interval"]]
    ctx[:, C["t"]] = t
    ctx[:, C["time_left"]] = np.maximum(world[:, W["horizon"]] - t, 0.0)
    ctx[:, C["active_facilities"]] = active
    ctx[:, C["employed"]] = employed
    ctx[:, C["free"]] = free
    ctx[:, C["busy"]] = busy
    ctx[:, C["open_requests"]] = open_requests
    ctx[:, C["facilities_per_person"]] = active / _safe(employed)
    ctx[:, C["open_per_free"]] = open_requests / _safe(free)
    ctx[:, C["load_per_person"]] = (busy + open_requests) / _safe(employed)
    out = dict(obs)
    out["facilities"] = fac.astype(np.float32)
    out["personnel"] = per.astype(np.float32)
    out["context"] = ctx.astype(np.float32)
    out["units"] = world[:, [W[u] for u in UNIT_FEATURES]].astype(np.float32)
    return out


def scaled_world(config: ScenarioConfig, k: float) -> ScenarioConfig:
    """The same world in other units: grid side, speed and the heat map's width (``heat_sigma``) times ``k``.

    Only for worlds whose facility layout is the default (random by the heat map); a
    layout of fixed sites is in cells and would need its sites moved too, so any other
    layout is refused (a ValueError of one line).
    """
    if config.layout.kind != "uniform":
        raise ValueError(f"scaled_world: {config.name!r} has a {config.layout.kind!r} facility layout, whose "
                         "positions and spreads are in cells; allowed: a world with the 'uniform' layout")
    return config.replace(name=f"{config.name}-x{k:g}", grid_width=int(round(config.grid_width * k)),
                          grid_height=int(round(config.grid_height * k)), speed=config.speed * k,
                          heat_sigma=config.heat_sigma * k)
