"""The compiled transition core: one environment ``b`` of a batch at a time.

A step of environment b at time t (DESIGN.md section 1; ``docs/model.md`` has every
rule with its source):

1. ``exogenous`` (run at the *start* of step t, before the decisions are observed):
   workforce transitions due at t (onboarding ends, a let-go person whose notice is
   over and who is idle or returning leaves), facility exits, facility arrivals
   (lowest free slot; dropped when none is free), then failures of operational
   facilities (each spends ``request_hazard[t]`` of its exponential clock).
2. ``apply_actions``: dispatch (facility by facility in slot order), then the
   workforce action with its positioning weights. Impossible actions are ignored
   and counted.
3. ``advance``: downtime is recorded, then every person moves ``speed`` cells
   (Manhattan, x first) or services; a visit's end draws its repair outcome.
4. ``record_metrics``: WC, PUR, AFD, utilities and NSW of step t.
5. ``t += 1`` and the exogenous events of the new step.

All functions mutate the arrays of :class:`wfbench.state.State` in place for
environment ``b`` only, so environments are independent (and can run in parallel).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wfbench.rng import STREAM_FAILURE, STREAM_PLACEMENT, STREAM_REPAIR, exponential, uniform
from wfbench.state import (
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
def retained(status_row, leave_row):
    """Employed people (onboarding included) who are not under notice."""
    n = 0
    for p in range(status_row.shape[0]):
        if status_row[p] != EMPTY and leave_row[p] < 0:
            n += 1
    return n


@njit(cache=True, inline="always")
def is_dispatchable(b, p, S):
    return dispatchable(S.per_status[b, p], S.per_leave[b, p])


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
    # workforce transitions due at t
    for p in range(N):
        st = S.per_status[b, p]
        if st == ONBOARDING and S.per_ready[b, p] <= t:
            S.per_status[b, p] = IDLE
            S.per_since[b, p] = t
        elif S.per_leave[b, p] >= 0 and S.per_leave[b, p] <= t and (st == IDLE or st == RETURNING):
            _remove_person(b, p, S)
    # facility exits, then arrivals into the lowest free slot
    for f in range(M):
        if S.fac_active[b, f] and S.fac_leave[b, f] <= t:
            _deactivate_facility(b, f, S)
    A = Tr.arr_t.shape[1]
    while S.arr_ptr[b] < A and Tr.arr_t[b, S.arr_ptr[b]] <= t:
        a = S.arr_ptr[b]
        S.arr_ptr[b] += 1
        slot = -1
        for f in range(M):
            if not S.fac_active[b, f]:
                slot = f
                break
        if slot < 0:
            S.counters[b, C_DROPPED] += 1
            continue
        _activate_facility(b, slot, Tr.arr_x[b, a], Tr.arr_y[b, a], Tr.arr_leave[b, a], t, S, key)
    # failures: operational facilities spend their failure clock
    lam = P.request_hazard[t]
    for f in range(M):
        if S.fac_active[b, f] and not S.fac_down[b, f] and S.fac_ok_since[b, f] < t:
            S.fac_hazard[b, f] -= lam
            if S.fac_hazard[b, f] <= 0.0:
                S.fac_down[b, f] = True
                S.fac_assigned[b, f] = -1
                S.fac_request[b, f] += 1
                S.fac_visits[b, f] = 0
                S.counters[b, C_REQUESTS] += 1


# -- 2. decisions -------------------------------------------------------------------------------
@njit(cache=True)
def _weights(b, S, w):
    """Positioning weights on active facilities; all-zero weights mean 'no preference'."""
    M = S.fac_active.shape[1]
    out = np.zeros(M)
    total = 0.0
    for f in range(M):
        if S.fac_active[b, f]:
            out[f] = w[f]
            total += w[f]
    if total <= 0.0:
        for f in range(M):
            if S.fac_active[b, f]:
                out[f] = 1.0
    return out


@njit(cache=True, inline="always")
def heat_at(b, S, w, sigma, x, y):
    """H(x, y) = sum_f w_f exp(-|(x, y) - x_f|^2 / (2 sigma^2)) over the weights ``w``."""
    h = 0.0
    inv = 1.0 / (2.0 * sigma * sigma)
    for f in range(S.fac_active.shape[1]):
        if w[f] > 0.0:
            dx = x - S.fac_x[b, f]
            dy = y - S.fac_y[b, f]
            h += w[f] * np.exp(-(dx * dx) * inv) * np.exp(-(dy * dy) * inv)
    return h


@njit(cache=True)
def heat_map(b, S, w, sigma, grid_w, grid_h):
    """The heat map over all cells, (grid_h, grid_w), by separable Gaussians."""
    M = S.fac_active.shape[1]
    inv = 1.0 / (2.0 * sigma * sigma)
    H = np.zeros((grid_h, grid_w))
    gx = np.empty(grid_w)
    for f in range(M):
        if w[f] <= 0.0:
            continue
        for x in range(grid_w):
            dx = x - S.fac_x[b, f]
            gx[x] = w[f] * np.exp(-(dx * dx) * inv)
        for y in range(grid_h):
            dy = y - S.fac_y[b, f]
            gy = np.exp(-(dy * dy) * inv)
            for x in range(grid_w):
                H[y, x] += gx[x] * gy
    return H


@njit(cache=True)
def _place(b, S, Tr, P, w):
    """Home cell of a hire: argmax of H (first cell in row-major order on ties) or a draw from H."""
    H = heat_map(b, S, w, P.sigma, P.grid_w, P.grid_h)
    if P.placement == 0:
        best = -1.0
        bx = 0
        by = 0
        for y in range(P.grid_h):
            for x in range(P.grid_w):
                if H[y, x] > best:
                    best = H[y, x]
                    bx = x
                    by = y
        return bx, by
    total = 0.0
    for y in range(P.grid_h):
        for x in range(P.grid_w):
            total += H[y, x]
    u = uniform(Tr.key[b], STREAM_PLACEMENT, S.n_hires[b], 0, 0) * total
    acc = 0.0
    for y in range(P.grid_h):
        for x in range(P.grid_w):
            acc += H[y, x]
            if acc > u:
                return x, y
    return P.grid_w - 1, P.grid_h - 1


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
    hx, hy = _place(b, S, Tr, P, _weights(b, S, w_hire))
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
    w = _weights(b, S, w_release)
    best = -1
    best_h = -1.0
    for p in range(N):
        if is_releasable(b, p, S) and S.per_level[b, p] == level:
            h = heat_at(b, S, w, P.sigma, S.per_hx[b, p], S.per_hy[b, p])
            if h > best_h:
                best_h = h
                best = p
    if best < 0:
        S.counters[b, C_RELEASE] += 1
        return
    S.per_leave[b, best] = S.t[b] + P.fire_delay
    S.counters[b, C_RELEASES] += 1


@njit(cache=True, inline="always")
def apply_actions(b, S, Tr, P, dispatch, workforce, positioning):
    """Dispatch row (M,) int (N = no-op), workforce code, positioning (2, M) weights."""
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    for f in range(M):
        p = dispatch[f]
        if p >= N:
            continue
        if not (S.fac_active[b, f] and S.fac_down[b, f] and S.fac_assigned[b, f] < 0):
            S.counters[b, C_NOT_REQ] += 1
            continue
        if S.per_dispatched[b, p] == t:
            S.counters[b, C_DUP] += 1
            continue
        if not is_dispatchable(b, p, S):
            S.counters[b, C_UNAVAIL] += 1
            continue
        S.per_status[b, p] = TO_FACILITY
        S.per_target[b, p] = f
        S.per_timer[b, p] = 0
        S.per_dispatched[b, p] = t
        S.fac_assigned[b, f] = p
    if workforce >= 1 and workforce <= 3:
        _hire(b, workforce - 1, positioning[0], S, Tr, P)
    elif workforce >= 4:
        _release(b, workforce - 4, positioning[1], S, P)


# -- 3. movement and service --------------------------------------------------------------------
@njit(cache=True, inline="always")
def _move_towards(b, p, tx, ty, speed, S):
    """Move up to ``speed`` cells, x first then y (a Manhattan path). True on arrival."""
    budget = speed
    dx = tx - S.per_x[b, p]
    if dx != 0.0:
        if abs(dx) <= budget:
            S.per_x[b, p] = tx
            budget -= abs(dx)
        else:
            S.per_x[b, p] += budget if dx > 0 else -budget
            return False
    dy = ty - S.per_y[b, p]
    if dy != 0.0:
        if abs(dy) <= budget:
            S.per_y[b, p] = ty
        else:
            S.per_y[b, p] += budget if dy > 0 else -budget
            return False
    return True


@njit(cache=True, inline="always")
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
def advance(b, S, Tr, P):
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    w = t % P.window
    for f in range(M):
        v = np.uint8(1) if (S.fac_active[b, f] and S.fac_down[b, f]) else np.uint8(0)
        S.fac_sum[b, f] += np.int64(v) - np.int64(S.fac_ring[b, f, w])
        S.fac_ring[b, f, w] = v
    for p in range(N):
        st = S.per_status[b, p]
        work = np.uint8(0)
        if st == TO_FACILITY:
            work = np.uint8(1)
            f = S.per_target[b, p]
            if _move_towards(b, p, np.float64(S.fac_x[b, f]), np.float64(S.fac_y[b, f]), P.speed, S):
                S.per_status[b, p] = SERVICING
                S.per_timer[b, p] = P.service_time
        elif st == SERVICING:
            work = np.uint8(1)
            S.per_timer[b, p] -= 1
            if S.per_timer[b, p] <= 0:
                _end_visit(b, p, S, Tr, P)
        elif st == RETURNING:
            work = np.uint8(1)
            if _move_towards(b, p, np.float64(S.per_hx[b, p]), np.float64(S.per_hy[b, p]), P.speed, S):
                S.per_status[b, p] = IDLE
        S.per_sum[b, p] += np.int64(work) - np.int64(S.per_ring[b, p, w])
        S.per_ring[b, p, w] = work


# -- 4. metrics ---------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def utility_pur(pur, target, tolerance):
    return 1.0 - max(0.0, abs(pur - target) - tolerance) / (max(target, 1.0 - target) - tolerance)


@njit(cache=True, inline="always")
def record_metrics(b, S, P):
    M = S.fac_active.shape[1]
    N = S.per_status.shape[1]
    t = S.t[b]
    W = P.window
    afd = 0.0
    n_fac = 0
    for f in range(M):
        if S.fac_active[b, f]:
            seen = min(W, t - S.fac_since[b, f] + 1)
            afd += S.fac_sum[b, f] / seen
            n_fac += 1
    afd = afd / n_fac if n_fac > 0 else 0.0
    pur = 0.0
    n_work = 0
    wc = 0.0
    head = 0
    for p in range(N):
        st = S.per_status[b, p]
        if st == EMPTY:
            continue
        head += 1
        wc += P.salaries[S.per_level[b, p]]
        if st >= IDLE:
            seen = min(W, t - S.per_since[b, p] + 1)
            pur += S.per_sum[b, p] / seen
            n_work += 1
    pur = pur / n_work if n_work > 0 else 0.0
    u_wc = 1.0 - wc / P.max_cost
    u_pur = utility_pur(pur, P.target, P.tolerance)
    u_afd = 1.0 - afd
    nsw = (u_wc * u_pur * u_afd) ** THIRD
    row = S.last[b]
    row[K_WC] = wc
    row[K_PUR] = pur
    row[K_AFD] = afd
    row[K_NSW] = nsw
    row[K_UWC] = u_wc
    row[K_UPUR] = u_pur
    row[K_UAFD] = u_afd
    row[K_HEAD] = head
    row[K_LOGH] = np.log(head) if head > 0 else 0.0
    for k in range(row.shape[0]):
        S.totals[b, k] += row[k]
    if S.series.shape[1] > 0:
        for k in range(row.shape[0]):
            S.series[b, t, k] = row[k]


# -- the step -----------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def step_env(b, S, Tr, P, dispatch, workforce, positioning):
    """One full step of environment b; returns its reward (NSW of the step)."""
    apply_actions(b, S, Tr, P, dispatch, workforce, positioning)
    advance(b, S, Tr, P)
    record_metrics(b, S, P)
    S.t[b] += 1
    if S.t[b] < P.horizon:
        exogenous(b, S, Tr, P)
    return S.last[b, K_NSW]


@njit(cache=True)
def reset_batch(S, Tr, P):
    for b in range(S.t.shape[0]):
        reset_env(b, S, Tr, P)


@njit(cache=True)
def step_batch(S, Tr, P, dispatch, workforce, positioning):
    """Step every environment of the batch; ``dispatch`` (B, M), ``workforce`` (B,), ``positioning`` (B, 2, M)."""
    for b in range(S.t.shape[0]):
        step_env(b, S, Tr, P, dispatch[b], workforce[b], positioning[b])
