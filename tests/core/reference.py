"""A small, readable per-entity reference implementation of one environment.

It follows docs/model.md rule by rule with plain Python objects and shares nothing with
the compiled core except the counter-based draws (wfbench.core.rng) and the trace. The
differential test runs both on the same traces and actions and demands identical
trajectories and metrics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from wfbench.core.rng import STREAM_FAILURE, STREAM_PLACEMENT, STREAM_REPAIR, exponential, uniform

EMPTY, ONBOARDING, IDLE, TO_FACILITY, SERVICING, RETURNING = range(6)


@dataclass
class Facility:
    active: bool = False
    x: int = 0
    y: int = 0
    down: bool = False
    assigned: int = -1
    hazard: float = 0.0
    draws: int = 0
    request: int = -1
    visits: int = 0
    leave: int = 0
    since: int = 0
    ok_since: int = 0
    history: list = field(default_factory=list)  # (t, down) for the steps recorded


@dataclass
class Person:
    status: int = EMPTY
    level: int = 0
    hx: int = 0
    hy: int = 0
    x: float = 0.0
    y: float = 0.0
    target: int = -1
    timer: int = 0
    ready: int = 0
    leave: int = -1
    since: int = 0
    dispatched: int = -1
    history: list = field(default_factory=list)  # (t, worked)


class ReferenceEnv:
    def __init__(self, config, trace, b=0):
        self.c = config
        self.key = trace.key[b]
        self.tr = trace
        self.b = b
        self.hazard = config.request_schedule.multipliers(config.horizon) / config.request_interval
        M, N = config.max_facilities, config.max_personnel
        self.fac = [Facility() for _ in range(M)]
        self.per = [Person() for _ in range(N)]
        self.t = 0
        self.arr = 0
        self.n_hires = 0
        self.counts = {k: 0 for k in ("not_req", "unavail", "dup", "hire", "release", "dropped", "hires",
                                      "releases", "requests", "visits", "repairs")}
        self.metrics = []
        tr, b = trace, b
        for f in range(M):
            if tr.fac0_active[b, f]:
                self._activate(f, int(tr.fac0_x[b, f]), int(tr.fac0_y[b, f]), int(tr.fac0_leave[b, f]))
        for p in range(N):
            if tr.per0_active[b, p]:
                x, y = int(tr.per0_x[b, p]), int(tr.per0_y[b, p])
                self.per[p] = Person(status=IDLE, level=int(tr.per0_level[b, p]), hx=x, hy=y, x=float(x), y=float(y))
        self.exogenous()

    # facilities -------------------------------------------------------------
    def _new_clock(self, f):
        fac = self.fac[f]
        fac.hazard = exponential(self.key, STREAM_FAILURE, f, fac.draws, 0)
        fac.draws += 1

    def _activate(self, f, x, y, leave):
        old = self.fac[f]
        self.fac[f] = Facility(active=True, x=x, y=y, leave=leave, since=self.t, ok_since=self.t, draws=old.draws,
                               request=old.request)
        self._new_clock(f)

    def _send_home(self, p):
        per = self.per[p]
        per.target = -1
        per.timer = 0
        per.status = IDLE if (per.x == per.hx and per.y == per.hy) else RETURNING

    def exogenous(self):
        t = self.t
        for p, per in enumerate(self.per):
            if per.status == ONBOARDING and per.ready <= t:
                per.status = IDLE
                per.since = t
            elif per.leave >= 0 and per.leave <= t and per.status in (IDLE, RETURNING):
                self.per[p] = Person(level=per.level, hx=per.hx, hy=per.hy, x=per.x, y=per.y)
        for f, fac in enumerate(self.fac):
            if fac.active and fac.leave <= t:
                if fac.assigned >= 0 and self.per[fac.assigned].target == f:
                    self._send_home(fac.assigned)
                fac.active, fac.down, fac.assigned, fac.history = False, False, -1, []
        arr_t = self.tr.arr_t[self.b]
        while self.arr < len(arr_t) and arr_t[self.arr] <= t:
            a = self.arr
            self.arr += 1
            free = [f for f, fac in enumerate(self.fac) if not fac.active]
            if not free:
                self.counts["dropped"] += 1
                continue
            self._activate(free[0], int(self.tr.arr_x[self.b, a]), int(self.tr.arr_y[self.b, a]),
                           int(self.tr.arr_leave[self.b, a]))
        for fac in self.fac:
            if fac.active and not fac.down and fac.ok_since < t:
                fac.hazard -= self.hazard[t]
                if fac.hazard <= 0.0:
                    fac.down, fac.assigned, fac.visits = True, -1, 0
                    fac.request += 1
                    self.counts["requests"] += 1

    # decisions --------------------------------------------------------------
    def _weights(self, w):
        out = [w[f] if fac.active else 0.0 for f, fac in enumerate(self.fac)]
        if sum(out) <= 0.0:
            out = [1.0 if fac.active else 0.0 for fac in self.fac]
        return out

    def _heat(self, w, x, y):
        inv = 1.0 / (2.0 * self.c.heat_sigma * self.c.heat_sigma)
        return sum(w[f] * math.exp(-((x - fac.x) * (x - fac.x)) * inv) * math.exp(-((y - fac.y) * (y - fac.y)) * inv)
                   for f, fac in enumerate(self.fac) if w[f] > 0.0)

    def _place(self, w):
        cells = [(x, y) for y in range(self.c.grid_height) for x in range(self.c.grid_width)]
        heat = [self._heat(w, x, y) for x, y in cells]
        if self.c.placement == "argmax":
            return cells[max(range(len(cells)), key=lambda i: (heat[i], -i))]
        u = uniform(self.key, STREAM_PLACEMENT, self.n_hires, 0, 0) * sum(heat)
        acc = 0.0
        for (x, y), h in zip(cells, heat, strict=True):
            acc += h
            if acc > u:
                return x, y
        return cells[-1]

    def act(self, dispatch, workforce, positioning):
        t, N = self.t, len(self.per)
        for f, p in enumerate(dispatch):
            p = int(p)
            if p == N:
                continue
            fac = self.fac[f]
            if not (fac.active and fac.down and fac.assigned < 0):
                self.counts["not_req"] += 1
            elif self.per[p].dispatched == t:
                self.counts["dup"] += 1
            elif not (self.per[p].status in (IDLE, RETURNING) and self.per[p].leave < 0):
                self.counts["unavail"] += 1
            else:
                per = self.per[p]
                per.status, per.target, per.timer, per.dispatched = TO_FACILITY, f, 0, t
                fac.assigned = p
        if 1 <= workforce <= 3:
            free = [p for p, per in enumerate(self.per) if per.status == EMPTY]
            if not free:
                self.counts["hire"] += 1
            else:
                x, y = self._place(self._weights(positioning[0]))
                self.per[free[0]] = Person(status=ONBOARDING, level=workforce - 1, hx=x, hy=y, x=float(x),
                                           y=float(y), ready=t + self.c.hire_delay, since=t + self.c.hire_delay)
                self.n_hires += 1
                self.counts["hires"] += 1
        elif workforce >= 4:
            retained = sum(1 for per in self.per if per.status != EMPTY and per.leave < 0)
            w = self._weights(positioning[1])
            cands = [p for p, per in enumerate(self.per)
                     if per.status >= IDLE and per.leave < 0 and per.level == workforce - 4]
            if retained <= self.c.min_personnel or not cands:
                self.counts["release"] += 1
            else:
                best = max(cands, key=lambda p: (self._heat(w, self.per[p].hx, self.per[p].hy), -p))
                self.per[best].leave = t + self.c.fire_delay
                self.counts["releases"] += 1

    # movement -----------------------------------------------------------------
    def _move(self, per, tx, ty):
        budget = self.c.speed
        for axis, target in (("x", tx), ("y", ty)):
            d = target - getattr(per, axis)
            if d == 0:
                continue
            if abs(d) <= budget:
                setattr(per, axis, float(target))
                budget -= abs(d)
            else:
                setattr(per, axis, getattr(per, axis) + (budget if d > 0 else -budget))
                return False
        return True

    def advance(self):
        t = self.t
        for fac in self.fac:
            if fac.active:
                fac.history.append((t, fac.down))
        for p, per in enumerate(self.per):
            worked = per.status in (TO_FACILITY, SERVICING, RETURNING)
            if per.status == TO_FACILITY:
                fac = self.fac[per.target]
                if self._move(per, fac.x, fac.y):
                    per.status, per.timer = SERVICING, self.c.service_time
            elif per.status == SERVICING:
                per.timer -= 1
                if per.timer <= 0:
                    f = per.target
                    fac = self.fac[f]
                    u = uniform(self.key, STREAM_REPAIR, f, fac.request, fac.visits)
                    fac.visits += 1
                    self.counts["visits"] += 1
                    if u < self.c.base_fix_rate * self.c.level_multipliers[per.level]:
                        fac.down, fac.ok_since = False, t
                        self.counts["repairs"] += 1
                        self._new_clock(f)
                    fac.assigned = -1
                    self._send_home(p)
            elif per.status == RETURNING:
                if self._move(per, per.hx, per.hy):
                    per.status = IDLE
            if per.status != EMPTY:
                per.history.append((t, worked))

    def record(self):
        t, W = self.t, self.c.window

        def rolling(history, since):
            return sum(1 for s, v in history if v and s > t - W) / min(W, t - since + 1)

        afds = [rolling(f.history, f.since) for f in self.fac if f.active]
        afd = sum(afds) / len(afds) if afds else 0.0
        working = [p for p in self.per if p.status >= IDLE]
        purs = [rolling([(s, v) for s, v in p.history if s >= p.since], p.since) for p in working]
        pur = sum(purs) / len(purs) if purs else 0.0
        wc = sum(self.c.level_salaries[p.level] for p in self.per if p.status != EMPTY)
        u_wc = 1.0 - wc / self.c.max_workforce_cost
        tgt, tol = self.c.target_utilization, self.c.utilization_tolerance
        u_pur = 1.0 - max(0.0, abs(pur - tgt) - tol) / (max(tgt, 1.0 - tgt) - tol)
        u_afd = 1.0 - afd
        self.metrics.append((wc, pur, afd, (u_wc * u_pur * u_afd) ** (1.0 / 3.0)))

    def step(self, dispatch, workforce, positioning):
        self.act(dispatch, workforce, positioning)
        self.advance()
        self.record()
        self.t += 1
        if self.t < self.c.horizon:
            self.exogenous()
