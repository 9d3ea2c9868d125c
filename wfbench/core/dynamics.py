"""The compiled transition core: one environment ``b`` of a batch at a time.

``exogenous`` (workforce transitions, facility exits, arrivals, failures), ``apply_dispatch``
then ``apply_workforce`` (impossible actions ignored and counted), ``advance`` (downtime, then
movement or service; a visit's end draws its repair outcome) and ``record_metrics`` (the KPIs,
utilities and ``NSW_t`` of the step) make up ``step_env``. Every function mutates the arrays of
:class:`wfbench.core.state.State` in place for environment ``b`` only, so environments are
independent and can run in parallel. The order of a step: ``docs/design.md``, "One time step";
every rule with its source: ``docs/model.md``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wfbench.core.placement import gauss_table, heat_at, place_hire, positioning_weights
from wfbench.core.rng import STREAM_FAILURE, STREAM_REPAIR, exponential, uniform
from wfbench.core.state import (
    C_DROPPED,
    C_DUP,
    C_HIRE,
    C_HIRES,
    C_NOT_REQ,
    C_RELEASE,
    C_RELEASES,
    C_REPAIRS,
    C_REQUESTS,
    C_UNAVAIL,
    C_VISITS,
    EMPTY,
    IDLE,
    K_AFD,
    K_HEAD,
    K_LOGH,
    K_NSW,
    K_PUR,
    K_UAFD,
    K_UPUR,
    K_UWC,
    K_WC,
    ONBOARDING,
    RETURNING,
    SERVICING,
    TO_FACILITY,
)

THIRD = 1.0 / 3.0


# -- entity helpers ------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _draw_failure_clock(b, f, S, key):
    S.fac_hazard[b, f] = exponential(key, STREAM_FAILURE, f, S.fac_draws[b, f], 0)
    S.fac_draws[b, f] += 1


@njit(cache=True)
def _activate_facility(b, f, x, y, leave, t, S, key):
    S.fac_active[b, f] = True
    S.fac_x[b, f] = x
    S.fac_y[b, f] = y
    S.fac_down[b, f] = False
    S.fac_assigned[b, f] = -1
    S.fac_visits[b, f] = 0
    S.fac_leave[b, f] = leave
    S.fac_since[b, f] = t
    S.fac_ok_since[b, f] = t
    S.fac_sum[b, f] = 0
    S.fac_ring[b, f, :] = 0
    _draw_failure_clock(b, f, S, key)


@njit(cache=True, inline="always")
def _person_goes_home(b, p, S):
    S.per_target[b, p] = -1
    S.per_timer[b, p] = 0
    if S.per_x[b, p] == S.per_hx[b, p] and S.per_y[b, p] == S.per_hy[b, p]:
        S.per_status[b, p] = IDLE
    else:
        S.per_status[b, p] = RETURNING


@njit(cache=True)
def _deactivate_facility(b, f, S):
    p = S.fac_assigned[b, f]
    if p >= 0 and S.per_target[b, p] == f:
        _person_goes_home(b, p, S)  # the job is cancelled
    S.fac_active[b, f] = False
    S.fac_down[b, f] = False
    S.fac_assigned[b, f] = -1
    S.fac_sum[b, f] = 0
    S.fac_ring[b, f, :] = 0


@njit(cache=True)
def _remove_person(b, p, S):
    S.per_status[b, p] = EMPTY
    S.per_target[b, p] = -1
    S.per_timer[b, p] = 0
    S.per_leave[b, p] = -1
    S.per_dispatched[b, p] = -1
    S.per_sum[b, p] = 0
    S.per_ring[b, p, :] = 0


@njit(cache=True, inline="always")
def dispatchable(status, leave):
    """Idle or returning, and not under notice: may be sent to a request."""
    return (status == IDLE or status == RETURNING) and leave < 0


@njit(cache=True, inline="always")
def releasable(status, leave):
    """Onboarded and not under notice: may be let go."""
    return status >= IDLE and leave < 0


@njit(cache=True, inline="always")
def kept_on(status, leave):
    """Employed (onboarding included) and not under notice: counts toward ``min_personnel``."""
    return status != EMPTY and leave < 0


@njit(cache=True, inline="always")
def retained(status_row, leave_row):
    """Employed people (onboarding included) who are not under notice."""
    n = 0
    for p in range(status_row.shape[0]):
        if kept_on(status_row[p], leave_row[p]):
            n += 1
    return n


@njit(cache=True, inline="always")
def is_releasable(b, p, S):
    return releasable(S.per_status[b, p], S.per_leave[b, p])


@njit(cache=True, inline="always")
def retained_headcount(b, S):
    return retained(S.per_status[b], S.per_leave[b])


# -- reset ------------------------------------------------------------------------------------
@njit(cache=True)
def reset_env(b, S, Tr, P):
    """Initial state of environment b from its trace, then the exogenous events of t = 0."""
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    key = Tr.key[b]
    S.t[b] = 0
    S.arr_ptr[b] = 0
    S.n_hires[b] = 0
    for f in range(M):
        S.fac_draws[b, f] = 0
        S.fac_request[b, f] = -1
        _deactivate_facility(b, f, S)
        S.fac_x[b, f] = 0
        S.fac_y[b, f] = 0
        S.fac_hazard[b, f] = 0.0
        S.fac_visits[b, f] = 0
        S.fac_leave[b, f] = 0
        S.fac_since[b, f] = 0
        S.fac_ok_since[b, f] = 0
    for p in range(N):
        _remove_person(b, p, S)
        S.per_level[b, p] = 0
        S.per_hx[b, p] = 0
        S.per_hy[b, p] = 0
        S.per_x[b, p] = 0.0
        S.per_y[b, p] = 0.0
        S.per_ready[b, p] = 0
        S.per_since[b, p] = 0
    for f in range(M):
        if Tr.fac0_active[b, f]:
            _activate_facility(b, f, Tr.fac0_x[b, f], Tr.fac0_y[b, f], Tr.fac0_leave[b, f], 0, S, key)
    for p in range(N):
        if Tr.per0_active[b, p]:
            S.per_status[b, p] = IDLE
            S.per_level[b, p] = Tr.per0_level[b, p]
            S.per_hx[b, p] = Tr.per0_x[b, p]
            S.per_hy[b, p] = Tr.per0_y[b, p]
            S.per_x[b, p] = Tr.per0_x[b, p]
            S.per_y[b, p] = Tr.per0_y[b, p]
    S.counters[b, :] = 0
    S.last[b, :] = 0.0
    S.totals[b, :] = 0.0
    if S.series.shape[1] > 0:
        S.series[b, :, :] = 0.0
    exogenous(b, S, Tr, P)


# -- 1. exogenous events -------------------------------------------------------------------------
@njit(cache=True, inline="always")
def exogenous(b, S, Tr, P):
    t = S.t[b]
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    key = Tr.key[b]
    status = S.per_status
    ready = S.per_ready
    leave = S.per_leave
    fac_active = S.fac_active
    fac_leave = S.fac_leave
    fac_down = S.fac_down
    fac_ok_since = S.fac_ok_since
    fac_hazard = S.fac_hazard
    # workforce transitions due at t
    for p in range(N):
        st = status[b, p]
        if st == ONBOARDING and ready[b, p] <= t:
            status[b, p] = IDLE
            S.per_since[b, p] = t
        elif leave[b, p] >= 0 and leave[b, p] <= t and (st == IDLE or st == RETURNING):
            _remove_person(b, p, S)
    # facility exits, and failures: operational facilities spend their failure clock. One
    # pass does both: a slot that exits is inactive for the failure rule, and an arrival
    # (below) only fills an inactive slot and cannot fail in its first step
    lam = P.request_hazard[t]
    for f in range(M):
        if not fac_active[b, f]:
            continue
        if fac_leave[b, f] <= t:
            _deactivate_facility(b, f, S)
        elif not fac_down[b, f] and fac_ok_since[b, f] < t:
            fac_hazard[b, f] -= lam
            if fac_hazard[b, f] <= 0.0:
                _open_request(b, f, S)
    # arrivals into the lowest free slot
    A = Tr.arr_t.shape[1]
    arr_t = Tr.arr_t
    while S.arr_ptr[b] < A and arr_t[b, S.arr_ptr[b]] <= t:
        a = S.arr_ptr[b]
        S.arr_ptr[b] += 1
        slot = -1
        for f in range(M):
            if not fac_active[b, f]:
                slot = f
                break
        if slot < 0:
            S.counters[b, C_DROPPED] += 1
            continue
        _activate_facility(b, slot, Tr.arr_x[b, a], Tr.arr_y[b, a], Tr.arr_leave[b, a], t, S, key)


@njit(cache=True)
def _open_request(b, f, S):
    S.fac_down[b, f] = True
    S.fac_assigned[b, f] = -1
    S.fac_request[b, f] += 1
    S.fac_visits[b, f] = 0
    S.counters[b, C_REQUESTS] += 1


# -- 2. decisions -------------------------------------------------------------------------------
@njit(cache=True)
def _hire(b, level, w_hire, S, Tr, P):
    N = S.per_status.shape[1]
    slot = -1
    for p in range(N):
        if S.per_status[b, p] == EMPTY:
            slot = p
            break
    if slot < 0:
        S.counters[b, C_HIRE] += 1
        return
    hx, hy = place_hire(b, S, Tr, P, positioning_weights(b, S, w_hire))
    t = S.t[b]
    _remove_person(b, slot, S)
    S.per_status[b, slot] = ONBOARDING
    S.per_level[b, slot] = level
    S.per_hx[b, slot] = hx
    S.per_hy[b, slot] = hy
    S.per_x[b, slot] = hx
    S.per_y[b, slot] = hy
    S.per_ready[b, slot] = t + P.hire_delay
    S.per_since[b, slot] = t + P.hire_delay
    S.n_hires[b] += 1
    S.counters[b, C_HIRES] += 1


@njit(cache=True)
def _release(b, level, w_release, S, P):
    N = S.per_status.shape[1]
    if retained_headcount(b, S) <= P.min_personnel:
        S.counters[b, C_RELEASE] += 1
        return
    w = positioning_weights(b, S, w_release)
    g = gauss_table(P.sigma, max(P.grid_w, P.grid_h))
    best = -1
    best_h = -1.0
    for p in range(N):
        if is_releasable(b, p, S) and S.per_level[b, p] == level:
            h = heat_at(b, S, w, g, S.per_hx[b, p], S.per_hy[b, p])
            if h > best_h:
                best_h = h
                best = p
    if best < 0:
        S.counters[b, C_RELEASE] += 1
        return
    S.per_leave[b, best] = S.t[b] + P.fire_delay
    S.counters[b, C_RELEASES] += 1


@njit(cache=True, inline="always")
def apply_dispatch(b, S, dispatch):
    """Dispatch row (M,) int (N = no-op), facility by facility in slot order."""
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    fac_active = S.fac_active
    fac_down = S.fac_down
    fac_assigned = S.fac_assigned
    dispatched = S.per_dispatched
    status = S.per_status
    leave = S.per_leave
    for f in range(M):
        p = dispatch[f]
        if p >= N:
            continue
        if not (fac_active[b, f] and fac_down[b, f] and fac_assigned[b, f] < 0):
            S.counters[b, C_NOT_REQ] += 1
            continue
        if dispatched[b, p] == t:
            S.counters[b, C_DUP] += 1
            continue
        if not dispatchable(status[b, p], leave[b, p]):
            S.counters[b, C_UNAVAIL] += 1
            continue
        status[b, p] = TO_FACILITY
        S.per_target[b, p] = f
        S.per_timer[b, p] = 0
        dispatched[b, p] = t
        fac_assigned[b, f] = p


@njit(cache=True, _nrt=True)  # allocates (see step_env)
def apply_workforce(b, S, Tr, P, workforce, positioning):
    """Workforce code (0 no-op, 1 + level hire, 4 + level let go) with the positioning (2, M) weights."""
    if workforce >= 1 and workforce <= 3:
        _hire(b, workforce - 1, positioning[0], S, Tr, P)
    elif workforce >= 4:
        _release(b, workforce - 4, positioning[1], S, P)


# -- 3 and 4. movement, service and the metrics of the step ---------------------------------------
@njit(cache=True, inline="always")
def _move_towards(x, y, tx, ty, speed):
    """Move from (x, y) up to ``speed`` cells towards (tx, ty), x first then y (a Manhattan path).

    Returns the new position and whether it is the target.
    """
    budget = speed
    dx = tx - x
    if dx != 0.0:
        if abs(dx) <= budget:
            x = tx
            budget -= abs(dx)
        else:
            return x + (budget if dx > 0 else -budget), y, False
    dy = ty - y
    if dy != 0.0:
        if abs(dy) <= budget:
            y = ty
        else:
            return x, y + (budget if dy > 0 else -budget), False
    return x, y, True


@njit(cache=True)
def _end_visit(b, p, S, Tr, P):
    f = S.per_target[b, p]
    t = S.t[b]
    u = uniform(Tr.key[b], STREAM_REPAIR, f, S.fac_request[b, f], S.fac_visits[b, f])
    S.fac_visits[b, f] += 1
    S.counters[b, C_VISITS] += 1
    if u < P.base_fix_rate * P.level_mult[S.per_level[b, p]]:
        S.fac_down[b, f] = False
        S.fac_ok_since[b, f] = t
        S.counters[b, C_REPAIRS] += 1
        _draw_failure_clock(b, f, S, Tr.key[b])
    S.fac_assigned[b, f] = -1
    _person_goes_home(b, p, S)


@njit(cache=True, inline="always")
def utility_pur(pur, target, tolerance):
    return 1.0 - max(0.0, abs(pur - target) - tolerance) / (max(target, 1.0 - target) - tolerance)


@njit(cache=True, inline="always")
def advance(b, S, Tr, P):
    """Steps 3 and 4 in one pass over the slots: record downtime, move and serve, then the metrics.

    A facility's downtime indicator for step t is recorded before anybody moves; a
    person's work indicator and metric terms are taken after that person moved or
    served. A visit's end changes only its own person and facility, never another
    person's terms or any facility's downtime sum, so one pass gives the same numbers,
    summed in the same order, as separate passes.
    """
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    W = P.window
    w = t % W
    speed = P.speed
    service_time = P.service_time
    salaries = P.salaries
    fac_active = S.fac_active
    fac_down = S.fac_down
    fac_sum = S.fac_sum
    fac_ring = S.fac_ring
    fac_since = S.fac_since
    fac_x = S.fac_x
    fac_y = S.fac_y
    status = S.per_status
    level = S.per_level
    target = S.per_target
    timer = S.per_timer
    px = S.per_x
    py = S.per_y
    hx = S.per_hx
    hy = S.per_hy
    per_sum = S.per_sum
    per_ring = S.per_ring
    per_since = S.per_since
    afd = 0.0
    n_fac = 0
    for f in range(M):
        if fac_active[b, f]:
            v = np.uint8(1) if fac_down[b, f] else np.uint8(0)
        else:
            v = np.uint8(0)
        fac_sum[b, f] += np.int64(v) - np.int64(fac_ring[b, f, w])
        fac_ring[b, f, w] = v
        if fac_active[b, f]:
            afd += fac_sum[b, f] / min(W, t - fac_since[b, f] + 1)
            n_fac += 1
    pur = 0.0
    n_work = 0
    wc = 0.0
    head = 0
    for p in range(N):
        st = status[b, p]
        work = np.uint8(0)
        if st == TO_FACILITY:
            work = np.uint8(1)
            f = target[b, p]
            x, y, arrived = _move_towards(px[b, p], py[b, p], np.float64(fac_x[b, f]), np.float64(fac_y[b, f]), speed)
            px[b, p] = x
            py[b, p] = y
            if arrived:
                status[b, p] = SERVICING
                timer[b, p] = service_time
        elif st == SERVICING:
            work = np.uint8(1)
            timer[b, p] -= 1
            if timer[b, p] <= 0:
                _end_visit(b, p, S, Tr, P)
        elif st == RETURNING:
            work = np.uint8(1)
            x, y, arrived = _move_towards(px[b, p], py[b, p], np.float64(hx[b, p]), np.float64(hy[b, p]), speed)
            px[b, p] = x
            py[b, p] = y
            if arrived:
                status[b, p] = IDLE
        per_sum[b, p] += np.int64(work) - np.int64(per_ring[b, p, w])
        per_ring[b, p, w] = work
        st = status[b, p]
        if st != EMPTY:
            head += 1
            wc += salaries[level[b, p]]
            if st >= IDLE:
                pur += per_sum[b, p] / min(W, t - per_since[b, p] + 1)
                n_work += 1
    record_metrics(b, S, P, afd / n_fac if n_fac > 0 else 0.0, pur / n_work if n_work > 0 else 0.0, wc, head)


@njit(cache=True, inline="always")
def write_metrics(row, wc, pur, afd, nsw, u_wc, u_pur, u_afd, head):
    """One step's metrics into ``row`` (laid out as ``METRICS``): the KPIs, their utilities, NSW, the headcount."""
    row[K_WC] = wc
    row[K_PUR] = pur
    row[K_AFD] = afd
    row[K_NSW] = nsw
    row[K_UWC] = u_wc
    row[K_UPUR] = u_pur
    row[K_UAFD] = u_afd
    row[K_HEAD] = head
    row[K_LOGH] = np.log(head) if head > 0 else 0.0


@njit(cache=True, inline="always")
def record_metrics(b, S, P, afd, pur, wc, head):
    """WC, PUR, AFD, the utilities and NSW of step t into ``last``, ``totals`` and ``series``."""
    t = S.t[b]
    u_wc = 1.0 - wc / P.max_cost
    u_pur = utility_pur(pur, P.target, P.tolerance)
    u_afd = 1.0 - afd
    nsw = (u_wc * u_pur * u_afd) ** THIRD
    row = S.last[b]
    write_metrics(row, wc, pur, afd, nsw, u_wc, u_pur, u_afd, head)
    totals = S.totals
    for k in range(row.shape[0]):
        totals[b, k] += row[k]
    series = S.series
    if series.shape[1] > 0:
        for k in range(row.shape[0]):
            series[b, t, k] = row[k]


# -- the step -----------------------------------------------------------------------------------
# The entry points (``reset_batch``, ``step_batch`` and the whole-episode rollout) are
# compiled with numba's runtime (NRT) switched off. With it on, every array read out of
# the state tuple in branching code keeps an atomic reference-count increment and
# decrement that numba's pruning pass cannot remove (numba issue #2350): about 40% of a
# step, and a cache line that all threads fight over. Without the runtime nothing may
# allocate, so the few functions that do (hiring and letting go build a heat map) are
# compiled with ``_nrt=True`` set explicitly; numba would otherwise make them inherit the
# caller's setting. docs/performance.md has the measurements.
@njit(cache=True, inline="always")
def step_env(b, S, Tr, P, dispatch, workforce, positioning):
    """One full step of environment b; returns its reward (NSW of the step)."""
    apply_dispatch(b, S, dispatch)
    if workforce != 0:
        apply_workforce(b, S, Tr, P, workforce, positioning)
    advance(b, S, Tr, P)
    S.t[b] += 1
    if S.t[b] < P.horizon:
        exogenous(b, S, Tr, P)
    return S.last[b, K_NSW]


@njit(cache=True, _nrt=False)
def reset_batch(S, Tr, P):
    for b in range(S.t.shape[0]):
        reset_env(b, S, Tr, P)


@njit(cache=True, _nrt=False)
def step_batch(S, Tr, P, dispatch, workforce, positioning):
    """Step every environment of the batch; ``dispatch`` (B, M), ``workforce`` (B,), ``positioning`` (B, 2, M)."""
    for b in range(S.t.shape[0]):
        step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])
