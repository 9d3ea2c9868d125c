"""What the kernels of all three decisions share: rule codes, the ``hp`` layout, the policy state, distances.

The rules and their codes are read from the tables of :mod:`wfbench.policies.rules` when
this module is imported: the ``D_``, ``W_`` and ``P_`` constants are the codes of the
dispatch, workforce and positioning rules there (0: each decision's no-op), and the
``HP_`` constants the positions of the fields of ``hp`` that the kernels read. Each
decision reads its own row of the hyper-parameter matrix ``hp`` (3 x ``len(HP_FIELDS)``:
dispatch, workforce, positioning), so two parts of a composite never share a value by accident.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from wfbench.policies.rules import HYPERPARAMETERS, code

from wfbench.core.observe import FAC_X, FAC_Y, PER_HOME_X, PER_HOME_Y

# the codes of the rules (wfbench.policies.rules.RULES) that the kernels of this package make
D_NOOP = code("dispatch", "none")
D_NEAREST = code("dispatch", "nearest")
D_INVERSE = code("dispatch", "inverse-distance")  # inverse-distance sampling
D_RANDOM = code("dispatch", "random")
D_ASSIGN = code("dispatch", "assignment")  # optimal assignment (wfbench.solvers.lap.lap_min)
D_ASSIGN_SPARSE = code("dispatch", "assignment-sparse")  # ... on the k nearest (wfbench.solvers.lap.lap_sparse)
W_NOOP = code("workforce", "fixed")
W_THRESHOLD = code("workforce", "threshold")
W_EPSILON = code("workforce", "threshold-epsilon")  # epsilon-greedy threshold
W_RANDOM = code("workforce", "random")
W_STAFFING = code("workforce", "staffing")  # square-root staffing (wfbench.solvers.staffing)
P_NONE = code("positioning", "none")  # zeros
P_SPATIAL = code("positioning", "spatial")  # spatial averaging
P_GAUSSIAN = code("positioning", "spatial-gaussian")  # spatial averaging with Gaussian noise
P_RANDOM = code("positioning", "random")
P_FACILITY = code("positioning", "facility-location")  # p-median (wfbench.solvers.facility_location)
P_FACILITY_SPARSE = code("positioning", "facility-location-sparse")  # ... on the k nearest (p_median_sparse)

# The candidate graphs of the sparse solver rules (docs/solvers.md, "Sparse candidate graphs"): each open
# request considers its SPARSE_K_PEOPLE nearest dispatchable people, each p-median client its SPARSE_K_SITES
# nearest sites, each home its SPARSE_K_MEDIANS nearest medians (Manhattan distance, ties to the lower slot);
# chosen by measurement (benchmarks/sparse_k.py)
SPARSE_K_PEOPLE = 8
SPARSE_K_SITES = 8
SPARSE_K_MEDIANS = 8

# Layout of the hyper-parameter vector ``hp`` (wfbench.policies.rules.HYPERPARAMETERS: meanings and defaults).
HP_FIELDS: tuple[str, ...] = tuple(h.name for h in HYPERPARAMETERS)
HP_DEFAULTS: dict[str, float] = {h.name: h.default for h in HYPERPARAMETERS}
# the position of each field the kernels read
HP_HIGH = HP_FIELDS.index("high")
HP_LOW = HP_FIELDS.index("low")
HP_COOLDOWN = HP_FIELDS.index("cooldown")
HP_WARMUP = HP_FIELDS.index("warmup")
HP_EPS = HP_FIELDS.index("epsilon")
HP_P0 = HP_FIELDS.index("p_novice")
HP_P1 = HP_FIELDS.index("p_mid")
HP_P2 = HP_FIELDS.index("p_expert")
HP_SMOOTH = HP_FIELDS.index("smoothing")
HP_REQW = HP_FIELDS.index("request_weight")
HP_NOISE = HP_FIELDS.index("noise")
HP_SPEED = HP_FIELDS.index("speed")
HP_SERVICE = HP_FIELDS.index("service_time")
HP_FIX0 = HP_FIELDS.index("fix_novice")  # a level's is HP_FIX0 + level: the three follow each other
HP_FIX1 = HP_FIELDS.index("fix_mid")
HP_FIX2 = HP_FIELDS.index("fix_expert")
HP_REVISIT = HP_FIELDS.index("revisit_cost")
HP_UNASSIGNED = HP_FIELDS.index("unassigned_cost")
HP_BETA = HP_FIELDS.index("beta")
HP_HYST = HP_FIELDS.index("hysteresis")
HP_RATE = HP_FIELDS.index("rate_smoothing")
HP_REFRESH = HP_FIELDS.index("refresh")
HP_FLOOR = HP_FIELDS.index("demand_floor")


class PolicyState(NamedTuple):
    """Per-environment memory of the built-in policies."""

    keys: np.ndarray  # (B, 3) uint64 random key per decision (dispatch, workforce, positioning)
    cooldown_until: np.ndarray  # (B,) int64 first step a workforce action may be taken again
    demand: np.ndarray  # (B, M) float64 smoothed rate of new requests per facility slot
    prev_down: np.ndarray  # (B, M) int8 request flag seen at the previous step
    prev_active: np.ndarray  # (B, M) int8 active flag seen at the previous step
    rate: np.ndarray  # (B,) float64 staffing: smoothed number of new requests per step
    rate_prev_down: np.ndarray  # (B, M) int8 staffing: request flag seen at the previous step
    pos_cache: np.ndarray  # (B, 2, M) float64 facility-location: the maps of the last solve
    pos_next: np.ndarray  # (B,) int64 facility-location: step of the next solve
    prev_xy: np.ndarray  # (B, N, 2) float64 staffing: position at the previous step (NaN: not heading out)
    speed_seen: np.ndarray  # (B,) float64 staffing: largest one-step move seen while heading out (0: none yet)
    # scratch space of the dispatch kernels, so that they allocate nothing per step
    req_buf: np.ndarray  # (B, M) int64
    per_buf: np.ndarray  # (B, N) int64
    w_buf: np.ndarray  # (B, N) float64
    used_buf: np.ndarray  # (B, N) bool


def allocate_state(B: int, M: int, N: int) -> PolicyState:
    return PolicyState(
        keys=np.zeros((B, 3), dtype=np.uint64),
        cooldown_until=np.zeros(B, dtype=np.int64),
        demand=np.zeros((B, M), dtype=np.float64),
        prev_down=np.zeros((B, M), dtype=np.int8),
        prev_active=np.zeros((B, M), dtype=np.int8),
        rate=np.zeros(B, dtype=np.float64),
        rate_prev_down=np.zeros((B, M), dtype=np.int8),
        pos_cache=np.zeros((B, 2, M), dtype=np.float64),
        pos_next=np.zeros(B, dtype=np.int64),
        prev_xy=np.full((B, N, 2), np.nan),
        speed_seen=np.zeros(B, dtype=np.float64),
        req_buf=np.zeros((B, M), dtype=np.int64),
        per_buf=np.zeros((B, N), dtype=np.int64),
        w_buf=np.zeros((B, N), dtype=np.float64),
        used_buf=np.zeros((B, N), dtype=np.bool_),
    )


@njit(cache=True, inline="always")
def dist_to(O, b, f, x, y):
    """Manhattan distance from the cell (x, y) to facility slot f."""
    return abs(x - O.facilities[b, f, FAC_X]) + abs(y - O.facilities[b, f, FAC_Y])


@njit(cache=True, inline="always")
def retained_homes(b, O, hx, hy):
    """Homes of the people employed and not under notice (onboarding included); their count."""
    h = 0
    for p in range(O.personnel.shape[1]):
        if O.personnel_mask[b, p] == 1 and O.under_notice[b, p] == 0:
            hx[h] = O.personnel[b, p, PER_HOME_X]
            hy[h] = O.personnel[b, p, PER_HOME_Y]
            h += 1
    return h
