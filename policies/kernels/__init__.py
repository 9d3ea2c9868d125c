"""Compiled decision rules of the built-in policies, one environment ``b`` at a time.

Every kernel reads only the observation (:class:`wfbench.core.observe.Obs`) and its own
policy state, so the same kernel serves ``Policy.act(obs)`` and the compiled whole-
episode runner (:mod:`wfbench.policies.episode`), which therefore give identical results.
Randomized kernels draw from :func:`wfbench.core.rng.uniform` with the policy's own key per
environment, indexed by (step, purpose, item): a seed gives the same decisions alone
or inside any batch. Modules, as :mod:`wfbench.policies.oracle`, by decision: ``common``
(rule codes, the ``hp`` layout, the policy state), ``dispatch``, ``workforce``,
``positioning``, and ``act`` (all three for one environment). This package re-exports their names.
``forward`` is the roll-forward over them, imported by its own path: it steps a batch from its
current state under these kernels, and the oracles and the deployable lookaheads both score
their candidates with it.
"""

from wfbench.policies.kernels.act import act_batch, act_codes
from wfbench.policies.kernels.common import (
    D_ASSIGN,
    D_ASSIGN_SPARSE,
    D_INVERSE,
    D_NEAREST,
    D_NOOP,
    D_RANDOM,
    HP_BETA,
    HP_COOLDOWN,
    HP_DEFAULTS,
    HP_EPS,
    HP_FIELDS,
    HP_FIX0,
    HP_FIX1,
    HP_FIX2,
    HP_FLOOR,
    HP_HIGH,
    HP_HYST,
    HP_LOW,
    HP_NOISE,
    HP_P0,
    HP_P1,
    HP_P2,
    HP_RATE,
    HP_REFRESH,
    HP_REQW,
    HP_REVISIT,
    HP_SERVICE,
    HP_SMOOTH,
    HP_SPEED,
    HP_UNASSIGNED,
    HP_WARMUP,
    P_FACILITY,
    P_FACILITY_SPARSE,
    P_GAUSSIAN,
    P_NONE,
    P_RANDOM,
    P_SPATIAL,
    SPARSE_K_MEDIANS,
    SPARSE_K_PEOPLE,
    SPARSE_K_SITES,
    W_EPSILON,
    W_NOOP,
    W_RANDOM,
    W_STAFFING,
    W_THRESHOLD,
    PolicyState,
    allocate_state,
    dist_to,
    retained_homes,
)
from wfbench.policies.kernels.dispatch import (
    assignment_costs,
    dispatch_assignment,
    dispatch_assignment_sparse,
    dispatch_inverse_distance,
    dispatch_nearest,
    dispatch_random,
    fill_open_requests_and_free_people,
    open_requests_and_free_people,
    revisit_penalty,
)
from wfbench.policies.kernels.positioning import (
    observe_history,
    positioning_facility,
    positioning_facility_sparse,
    positioning_random,
    positioning_spatial,
    spatial_weights,
)
from wfbench.policies.kernels.workforce import (
    staffing_target,
    workforce_random,
    workforce_staffing,
    workforce_threshold,
)

__all__ = [
    "D_ASSIGN", "D_ASSIGN_SPARSE", "D_INVERSE", "D_NEAREST", "D_NOOP", "D_RANDOM", "HP_BETA", "HP_COOLDOWN",
    "HP_DEFAULTS", "HP_EPS", "HP_FIELDS", "HP_FIX0", "HP_FIX1", "HP_FIX2", "HP_FLOOR", "HP_HIGH", "HP_HYST", "HP_LOW",
    "HP_NOISE", "HP_P0", "HP_P1", "HP_P2", "HP_RATE", "HP_REFRESH", "HP_REQW", "HP_REVISIT", "HP_SERVICE",
    "HP_SMOOTH", "HP_SPEED", "HP_UNASSIGNED", "HP_WARMUP", "P_FACILITY", "P_FACILITY_SPARSE", "P_GAUSSIAN", "P_NONE",
    "P_RANDOM", "P_SPATIAL", "PolicyState", "SPARSE_K_MEDIANS", "SPARSE_K_PEOPLE", "SPARSE_K_SITES", "W_EPSILON",
    "W_NOOP", "W_RANDOM", "W_STAFFING", "W_THRESHOLD", "act_batch", "act_codes", "allocate_state", "assignment_costs",
    "dispatch_assignment", "dispatch_assignment_sparse", "dispatch_inverse_distance", "dispatch_nearest",
    "dispatch_random", "dist_to", "fill_open_requests_and_free_people", "observe_history",
    "open_requests_and_free_people", "positioning_facility", "positioning_facility_sparse", "positioning_random",
    "positioning_spatial", "retained_homes", "revisit_penalty", "spatial_weights", "staffing_target",
    "workforce_random", "workforce_staffing", "workforce_threshold",
]
