"""Observations: the paper's facility (M x 7) and personnel (N x 9) features, masks, globals.

Facility features: x, y, operational, requesting service, has a person assigned,
assigned person (-1 none), rolling downtime. Personnel features: home x, y, current
x, y, level, busy (assigned to a job), assigned facility (-1 none), heading (1 to a
facility, 0 otherwise), rolling utilization. Inactive slots are all zeros except the
-1 identifiers. Masks say which slots are active, who may be dispatched, which
requests are open and unassigned, and which actions are possible.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from wfbench.core import jit as _jit  # noqa: F401  (first: keys the numba cache of what follows)
from wfbench.core.dynamics import dispatchable, kept_on, releasable, step_env
from wfbench.core.kpis import KPI_NAMES
from wfbench.core.state import (
    EMPTY,
    IDLE,
    K_AFD,
    K_NSW,
    K_PUR,
    K_WC,
    N_WORKFORCE_ACTIONS,
    ONBOARDING,
    SERVICING,
    TO_FACILITY,
)

FACILITY_FEATURES = ("x", "y", "operational", "requesting", "assigned", "assigned_person", "downtime")
PERSONNEL_FEATURES = ("home_x", "home_y", "x", "y", "level", "busy", "assigned_facility", "heading_out", "utilization")
GLOBAL_FEATURES = (
    "time_fraction", "headcount", "onboarding", "under_notice", "novices", "mids", "experts",
    *KPI_NAMES, "active_facilities",
)
# column indices of the features, by name: kernels and shells read features through these
FAC_X, FAC_Y, FAC_OPERATIONAL, FAC_REQUESTING, FAC_ASSIGNED, FAC_PERSON, FAC_DOWNTIME = range(len(FACILITY_FEATURES))
(PER_HOME_X, PER_HOME_Y, PER_X, PER_Y, PER_LEVEL, PER_BUSY, PER_FACILITY, PER_HEADING_OUT,
 PER_UTILIZATION) = range(len(PERSONNEL_FEATURES))
G_TIME, G_HEAD, G_ONB, G_NOTICE, G_L0, G_L1, G_L2, G_WC, G_PUR, G_AFD, G_NSW, G_ACTIVE = range(len(GLOBAL_FEATURES))


class Obs(NamedTuple):
    """Batched observation buffers (leading axis B)."""

    facilities: np.ndarray  # (B, M, 7) float32
    personnel: np.ndarray  # (B, N, 9) float32
    facility_mask: np.ndarray  # (B, M) int8 active facility
    personnel_mask: np.ndarray  # (B, N) int8 employed (onboarding and under notice included)
    personnel_status: np.ndarray  # (B, N) int8 EMPTY..RETURNING
    under_notice: np.ndarray  # (B, N) int8
    dispatchable: np.ndarray  # (B, N) int8 idle or returning, not under notice
    requesting: np.ndarray  # (B, M) int8 open request with nobody assigned
    globals: np.ndarray  # (B, 12) float32
    dispatch_mask: np.ndarray  # (B, M, N + 1) int8 valid dispatch choices (last = no-op)
    workforce_mask: np.ndarray  # (B, 7) int8 valid workforce actions


def allocate_obs(B: int, M: int, N: int) -> Obs:
    return Obs(
        facilities=np.zeros((B, M, len(FACILITY_FEATURES)), dtype=np.float32),
        personnel=np.zeros((B, N, len(PERSONNEL_FEATURES)), dtype=np.float32),
        facility_mask=np.zeros((B, M), dtype=np.int8),
        personnel_mask=np.zeros((B, N), dtype=np.int8),
        personnel_status=np.zeros((B, N), dtype=np.int8),
        under_notice=np.zeros((B, N), dtype=np.int8),
        dispatchable=np.zeros((B, N), dtype=np.int8),
        requesting=np.zeros((B, M), dtype=np.int8),
        globals=np.zeros((B, len(GLOBAL_FEATURES)), dtype=np.float32),
        dispatch_mask=np.zeros((B, M, N + 1), dtype=np.int8),
        workforce_mask=np.zeros((B, N_WORKFORCE_ACTIONS), dtype=np.int8),
    )


@njit(cache=True, inline="always")
def observe_env(b, S, P, O, with_masks, full):
    """Fill the observation of environment b; ``with_masks`` also fills the (M, N + 1) dispatch mask.

    ``full=False`` (the compiled rollout of built-in policies) fills only what the
    built-in kernels read: facility x, y, request flags and downtime, personnel home,
    position, level and heading, the masks, and the utilization in ``globals``; the
    rest of the buffers is left as it was (a sixth of the time of a rollout step). A kernel
    that reads anything else must be added here: the test that compares the compiled
    rollout with stepping through ``Policy.act`` (full observations) catches a miss.
    """
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    W = P.window
    active = 0
    for f in range(M):
        row = O.facilities[b, f]
        if S.fac_active[b, f]:
            active += 1
            down = S.fac_down[b, f]
            a = S.fac_assigned[b, f]
            row[FAC_X] = S.fac_x[b, f]
            row[FAC_Y] = S.fac_y[b, f]
            row[FAC_REQUESTING] = 1.0 if down else 0.0
            if full:
                row[FAC_OPERATIONAL] = 0.0 if down else 1.0
                row[FAC_ASSIGNED] = 1.0 if a >= 0 else 0.0
                row[FAC_PERSON] = a
            row[FAC_DOWNTIME] = S.fac_sum[b, f] / max(1, min(W, t - S.fac_since[b, f]))
            O.facility_mask[b, f] = 1
            O.requesting[b, f] = 1 if (down and a < 0) else 0
        else:
            row[:] = 0.0
            if full:
                row[FAC_PERSON] = -1.0
            O.facility_mask[b, f] = 0
            O.requesting[b, f] = 0
    head = 0
    onb = 0
    notice = 0
    l0 = 0
    l1 = 0
    l2 = 0
    # for the workforce mask: a free slot, the retained headcount, who may be let go
    any_empty = False
    kept = 0
    rel0 = 0
    rel1 = 0
    rel2 = 0
    status = S.per_status[b]
    leave = S.per_leave[b]
    for p in range(N):
        row = O.personnel[b, p]
        st = status[p]
        if full:
            O.personnel_status[b, p] = st
        if st == EMPTY:
            if full:
                row[:] = 0.0
                row[PER_FACILITY] = -1.0
            O.personnel_mask[b, p] = 0
            O.dispatchable[b, p] = 0
            O.under_notice[b, p] = 0
            any_empty = True
            continue
        head += 1
        lv = S.per_level[b, p]
        rel = 1 if releasable(st, leave[p]) else 0
        if lv == 0:
            l0 += 1
            rel0 |= rel
        elif lv == 1:
            l1 += 1
            rel1 |= rel
        else:
            l2 += 1
            rel2 |= rel
        if st == ONBOARDING:
            onb += 1
        row[PER_HOME_X] = S.per_hx[b, p]
        row[PER_HOME_Y] = S.per_hy[b, p]
        row[PER_X] = S.per_x[b, p]
        row[PER_Y] = S.per_y[b, p]
        row[PER_LEVEL] = lv
        row[PER_HEADING_OUT] = 1.0 if st == TO_FACILITY else 0.0
        if full:
            row[PER_BUSY] = 1.0 if (st == TO_FACILITY or st == SERVICING) else 0.0
            row[PER_FACILITY] = S.per_target[b, p]
            since = S.per_since[b, p]
            row[PER_UTILIZATION] = S.per_sum[b, p] / max(1, min(W, t - since)) if st >= IDLE and t > since else 0.0
        O.personnel_mask[b, p] = 1
        on_notice = leave[p] >= 0
        O.dispatchable[b, p] = 1 if dispatchable(st, leave[p]) else 0
        O.under_notice[b, p] = 1 if on_notice else 0
        if on_notice:
            notice += 1
        if kept_on(st, leave[p]):
            kept += 1
    g = O.globals[b]
    g[G_PUR] = S.last[b, K_PUR]
    if full:
        g[G_TIME] = t / P.horizon
        g[G_HEAD] = head / N
        g[G_ONB] = onb / N
        g[G_NOTICE] = notice / N
        g[G_L0] = l0 / N
        g[G_L1] = l1 / N
        g[G_L2] = l2 / N
        g[G_WC] = S.last[b, K_WC] / P.max_cost
        g[G_AFD] = S.last[b, K_AFD]
        g[G_NSW] = S.last[b, K_NSW]
        g[11] = active / M
    # valid workforce actions: the no-op; a hire of any level while a slot is free; letting
    # go a level someone onboarded and not under notice has, unless that leaves the retained
    # headcount at min_personnel
    wm = O.workforce_mask[b]
    wm[0] = 1
    h = 1 if any_empty else 0
    wm[1] = h
    wm[2] = h
    wm[3] = h
    can_release = kept > P.min_personnel
    wm[4] = rel0 if can_release else 0
    wm[5] = rel1 if can_release else 0
    wm[6] = rel2 if can_release else 0
    if with_masks:
        for f in range(M):
            req = O.requesting[b, f] == 1
            for p in range(N):
                O.dispatch_mask[b, f, p] = 1 if (req and O.dispatchable[b, p] == 1) else 0
            O.dispatch_mask[b, f, N] = 1


# The batch entry points take a range lo..hi-1 of environments and release the GIL, so
# that wfbench.core.entrypoints.run_split can spread a batch over threads (environment b reads
# and writes only row b of every array: any split gives the same bits). One compiled
# function serves one thread and many; numba's prange would compile a second, parallel
# copy of the whole step (docs/performance.md, "Threads").
@njit(cache=True, _nrt=False, nogil=True)  # allocates nothing: no reference counting (see dynamics.step_env)
def observe_range(lo, hi, S, P, O, with_masks):
    """Fill the observations of environments lo..hi-1."""
    for b in range(lo, hi):
        observe_env(b, S, P, O, with_masks, True)


@njit(cache=True, _nrt=False, nogil=True)
def step_range(lo, hi, S, Tr, P, dispatch, workforce, positioning):
    """Step environments lo..hi-1; ``dispatch`` (B, M), ``workforce`` (B,), ``positioning`` (B, 2, M)."""
    for b in range(lo, hi):
        step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])


@njit(cache=True, _nrt=False, nogil=True)
def step_observe_range(lo, hi, S, Tr, P, O, dispatch, workforce, positioning, with_masks):
    """Step then observe environments lo..hi-1 in one call (one unboxing of the state for both)."""
    for b in range(lo, hi):
        step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])
        observe_env(b, S, P, O, with_masks, True)


def make_obs(M: int, N: int, facilities=(), people=(), t: int = 0) -> dict[str, np.ndarray]:
    """One hand-built observation (B = 1), for unit tests of policies and for benchmarks.

    ``facilities``: rows ``(x, y, requesting)``, active and operational unless requesting;
    ``people``: rows ``(home_x, home_y, x, y, level)``, employed, idle and dispatchable.
    Every workforce action is marked valid. Returns the dict a policy's ``act`` takes.
    """
    O = allocate_obs(1, M, N)
    for f, (x, y, req) in enumerate(facilities):
        O.facilities[0, f, :4] = (x, y, 0.0 if req else 1.0, 1.0 if req else 0.0)
        O.facilities[0, f, 5] = -1.0
        O.facility_mask[0, f] = 1
        O.requesting[0, f] = 1 if req else 0
    for p, (hx, hy, x, y, level) in enumerate(people):
        O.personnel[0, p, :5] = (hx, hy, x, y, level)
        O.personnel[0, p, 6] = -1.0
        O.personnel_mask[0, p] = 1
        O.dispatchable[0, p] = 1
        O.personnel_status[0, p] = IDLE
    O.workforce_mask[0, :] = 1
    obs = O._asdict()
    obs["t"] = np.array([t], dtype=np.int64)
    return obs
