"""Batched simulator state (struct of arrays) and the compiled-core parameters.

Entities are fixed slots with masks: facility slot f and personnel slot p of
environment b live at ``[b, f]`` and ``[b, p]``. The shape and dtype of every field is
written beside it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import METRICS as _KPI_METRICS

# Personnel status codes.
EMPTY, ONBOARDING, IDLE, TO_FACILITY, SERVICING, RETURNING = 0, 1, 2, 3, 4, 5
STATUS_NAMES = ("empty", "onboarding", "idle", "to_facility", "servicing", "returning")

# Workforce action codes: 0 no-op, 1 + level hire, 4 + level let go.
WF_NOOP = 0
N_WORKFORCE_ACTIONS = 7

# Counter columns (reported in ``info`` and in evaluation results).
COUNTERS = (
    "invalid_dispatch_not_requesting",  # dispatch to a facility without an open, unassigned request
    "invalid_dispatch_unavailable",  # dispatch of a person who is not idle or returning
    "invalid_dispatch_duplicate",  # the same person named for a second facility in one step
    "invalid_hire_no_slot",  # hire with every personnel slot taken
    "invalid_release_none",  # let go with nobody of that level eligible, or at min_personnel
    "arrivals_dropped",  # a facility arrival with every facility slot taken
    "hires",
    "releases",
    "requests",
    "visits",
    "repairs",
)
C_NOT_REQ, C_UNAVAIL, C_DUP, C_HIRE, C_RELEASE, C_DROPPED, C_HIRES, C_RELEASES, C_REQUESTS, C_VISITS, C_REPAIRS = range(
    len(COUNTERS)
)
INVALID_COUNTERS = COUNTERS[:5]

# Metric columns of ``last``, ``totals`` and ``series``: the KPI table's KPIs, utilities and extras
# (wfbench.core.kpis.METRICS), and the column of each that the compiled code writes, looked up by name.
METRICS = _KPI_METRICS
K_WC = METRICS.index("workforce_cost")
K_PUR = METRICS.index("utilization")
K_AFD = METRICS.index("downtime")
K_NSW = METRICS.index("nsw")
K_UWC = METRICS.index("u_cost")
K_UPUR = METRICS.index("u_utilization")
K_UAFD = METRICS.index("u_downtime")
K_HEAD = METRICS.index("headcount")
K_LOGH = METRICS.index("log_headcount")


class Params(NamedTuple):
    """Config scalars and tables in the form the compiled core takes."""

    grid_w: int
    grid_h: int
    horizon: int
    speed: float
    service_time: int
    hire_delay: int
    fire_delay: int
    window: int
    min_personnel: int
    base_fix_rate: float
    level_mult: np.ndarray  # (3,) float64
    salaries: np.ndarray  # (3,) float64
    max_cost: float
    target: float
    tolerance: float
    sigma: float
    placement: int  # 0 argmax, 1 sample
    request_hazard: np.ndarray  # (horizon + 1,) float64 failure hazard per step


def make_params(c: ScenarioConfig) -> Params:
    return Params(
        grid_w=c.grid_width, grid_h=c.grid_height, horizon=c.horizon, speed=float(c.speed),
        service_time=c.service_time, hire_delay=c.hire_delay, fire_delay=c.fire_delay, window=c.window,
        min_personnel=c.min_personnel, base_fix_rate=float(c.base_fix_rate),
        level_mult=np.asarray(c.level_multipliers, dtype=np.float64),
        salaries=np.asarray(c.level_salaries, dtype=np.float64), max_cost=float(c.max_workforce_cost),
        target=float(c.target_utilization), tolerance=float(c.utilization_tolerance), sigma=float(c.heat_sigma),
        placement=0 if c.placement == "argmax" else 1,
        request_hazard=c.request_schedule.multipliers(c.horizon) / c.request_interval,
    )


class State(NamedTuple):
    """Everything that changes during an episode, for B environments."""

    t: np.ndarray  # (B,) int64 current step
    arr_ptr: np.ndarray  # (B,) int64 next arrival of the trace
    n_hires: np.ndarray  # (B,) int64 hires so far (index of the placement draw)
    # facilities
    fac_active: np.ndarray  # (B, M) bool
    fac_x: np.ndarray  # (B, M) int64
    fac_y: np.ndarray  # (B, M) int64
    fac_down: np.ndarray  # (B, M) bool open service request
    fac_assigned: np.ndarray  # (B, M) int64 person on the request, -1 none
    fac_hazard: np.ndarray  # (B, M) float64 hazard left until the next failure
    fac_draws: np.ndarray  # (B, M) int64 failure-clock draws used by this slot
    fac_request: np.ndarray  # (B, M) int64 index of the slot's current request (-1 none yet)
    fac_visits: np.ndarray  # (B, M) int64 visits made to the current request
    fac_leave: np.ndarray  # (B, M) int64 exit step
    fac_since: np.ndarray  # (B, M) int64 step the facility became active
    fac_ok_since: np.ndarray  # (B, M) int64 step it last became operational
    fac_ring: np.ndarray  # (B, M, W) uint8 down indicator per step in the window
    fac_sum: np.ndarray  # (B, M) int64 down steps in the window
    # personnel
    per_status: np.ndarray  # (B, N) int64 EMPTY..RETURNING
    per_level: np.ndarray  # (B, N) int64 0 novice, 1 mid, 2 expert
    per_hx: np.ndarray  # (B, N) int64 home cell
    per_hy: np.ndarray  # (B, N) int64
    per_x: np.ndarray  # (B, N) float64 current position
    per_y: np.ndarray  # (B, N) float64
    per_target: np.ndarray  # (B, N) int64 facility of the current job, -1 none
    per_timer: np.ndarray  # (B, N) int64 service steps left
    per_ready: np.ndarray  # (B, N) int64 step onboarding ends
    per_leave: np.ndarray  # (B, N) int64 step the notice ends, -1 not let go
    per_since: np.ndarray  # (B, N) int64 step the person started work (onboarded)
    per_dispatched: np.ndarray  # (B, N) int64 step of the last dispatch
    per_ring: np.ndarray  # (B, N, W) uint8 work indicator per step in the window
    per_sum: np.ndarray  # (B, N) int64 work steps in the window
    # bookkeeping
    counters: np.ndarray  # (B, len(COUNTERS)) int64
    last: np.ndarray  # (B, len(METRICS)) float64 metrics of the last step
    totals: np.ndarray  # (B, len(METRICS)) float64 sums over the steps so far
    series: np.ndarray  # (B, horizon, len(METRICS)) float32 per-step metrics (S=0 disables)


def allocate(B: int, c: ScenarioConfig, keep_series: bool = True) -> State:
    M, N, W = c.max_facilities, c.max_personnel, c.window
    i = lambda *s: np.zeros(s, dtype=np.int64)  # noqa: E731
    f = lambda *s: np.zeros(s, dtype=np.float64)  # noqa: E731
    b = lambda *s: np.zeros(s, dtype=bool)  # noqa: E731
    u8 = lambda *s: np.zeros(s, dtype=np.uint8)  # noqa: E731
    return State(
        t=i(B), arr_ptr=i(B), n_hires=i(B),
        fac_active=b(B, M), fac_x=i(B, M), fac_y=i(B, M), fac_down=b(B, M), fac_assigned=i(B, M),
        fac_hazard=f(B, M), fac_draws=i(B, M), fac_request=i(B, M), fac_visits=i(B, M), fac_leave=i(B, M),
        fac_since=i(B, M), fac_ok_since=i(B, M), fac_ring=u8(B, M, W), fac_sum=i(B, M),
        per_status=i(B, N), per_level=i(B, N), per_hx=i(B, N), per_hy=i(B, N), per_x=f(B, N), per_y=f(B, N),
        per_target=i(B, N), per_timer=i(B, N), per_ready=i(B, N), per_leave=i(B, N), per_since=i(B, N),
        per_dispatched=i(B, N), per_ring=u8(B, N, W), per_sum=i(B, N),
        counters=i(B, len(COUNTERS)), last=f(B, len(METRICS)), totals=f(B, len(METRICS)),
        series=np.zeros((B, c.horizon if keep_series else 0, len(METRICS)), dtype=np.float32),
    )
