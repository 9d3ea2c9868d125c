"""Model predictive control: a rolling-horizon staffing MILP on a forecast, re-solved every R steps (issue #43).

Every ``R`` steps, for each environment, :class:`MPC` solves
:func:`wfbench.solvers.staffing_mpc.plan_staffing` (HiGHS, a node limit per solve) over the
next ``H`` steps and plays the plan's workforce actions; dispatch is the base's assignment.
The demand forecast is named apart: ``rates`` (``mpc-rates``, the world's public model from
``set_world``) or ``ma`` (``mpc-ma``, a moving average of observed requests). Its knobs, the
MILP's prices and a capacity scale are tunable (:attr:`MPC.tunable`); ``calibrate=True`` measures
the capacity from observed repairs (issue #53's diagnosis), ``backlog=True`` plans a fluid queue of
repair requests seeded from the requests waiting now (its second design). Nothing here reads the
trace, a seed's generator or the true state. The model in full: ``docs/policies.md``, "mpc".
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.lookahead.knobs import whole
from wfbench.policies.protocol import as_obs, seeds_array
from wfbench.policies.tunable import Param
from wfbench.solvers.staffing_mpc import StaffingInstance, plan_staffing

from wfbench.core.actions import AGENTS
from wfbench.core.config import ScenarioConfig, require_config
from wfbench.core.observation_v2 import W
from wfbench.core.observe import FAC_REQUESTING, FAC_X, FAC_Y, PER_HOME_X, PER_HOME_Y, PER_LEVEL
from wfbench.core.state import EMPTY, ONBOARDING, RETURNING, TO_FACILITY

FORECASTS = ("rates", "ma")
KNOBS = {"H": "steps of the plan", "R": "steps between two solves",
         "window": "steps of the moving average of observed requests (mpc-ma)",
         "node_limit": "HiGHS's branch-and-bound nodes per solve"}
DEFAULTS = {"H": 100, "R": 20, "window": 100}
BLOCK = 10  # steps per decision block of the MILP (plan_staffing's block)
SHORTFALL_COST = 1000.0  # per request per step not covered, salary units: a queue that outgrows its people never drains
# per solve, HiGHS's branch-and-bound nodes at most: a limit of work, so the plan is the same under any load (a
# wall-clock limit made it depend on the machine's speed); the largest solve measured on the held-out worlds took 17
NODE_LIMIT = 1000
ACTION_COST = 50.0  # per hire or let-go, salary units: what churn costs beyond the lags (a novice earns 1 a step)
# calibrate=True (issue #53): the capacity's correction is a ratio of repairs observed to repairs the model expects
# over the busy person-steps, both decayed by this much a step (a memory of about 200 steps, so the ratio follows the
# headcount: trips are longer with fewer people), with PRIOR_REPAIRS of the model's own rate as a prior
CALIBRATION_DECAY = 1.0 - 1.0 / 200.0
PRIOR_REPAIRS = 5.0
# backlog=True (issue #53's second design): a request waiting a step is priced at BACKLOG_WEIGHT times the score's
# exchange rate of downtime for payroll, max_personnel * the top salary / the active facilities (a facility down a
# step lowers u_AFD by 1 / active, a salary unit a step lowers u_WC by 1 / (max_personnel * top salary); 4 on paper-64)
BACKLOG_WEIGHT = 1.0
# what a tuner may search (wfbench tune), and a tuned file may set; the defaults above sit inside
TUNABLE: dict[str, Param] = {
    "H": Param(20, 300, "int"),
    "R": Param(5, 100, "int"),
    "window": Param(10, 400, "int"),
    "shortfall_cost": Param(10.0, 10000.0, "float", log=True),
    "action_cost": Param(1.0, 1000.0, "float", log=True),
    "capacity_scale": Param(0.5, 2.0),
}
# the option of a registered MPC preset (wfbench.policies.table.MPCPreset, in wfbench.policies.lookahead) -> the knobs
# it sets
PRESET_OPTIONS: dict[str, dict[str, bool]] = {"": {}, "calibrated": {"calibrate": True},
                                              "backlog": {"calibrate": True, "backlog": True}}
# with backlog=True the queue's price joins the tunable ones
BACKLOG_TUNABLE: dict[str, Param] = {"backlog_weight": Param(0.1, 100.0, "float", log=True)}


def knob(name: str, value: Any) -> int:
    """``value`` as an MPC knob's integer >= 1; ValueError of one line naming the knob otherwise."""
    return whole("mpc", name, value, KNOBS[name])


class MPC:
    """A rolling-horizon staffing MILP on a forecast (module docstring).

    Args:
        base: the compiled composite whose dispatch (and kernel state) is played, e.g.
            ``policies.get("solver-tuned-train")``.
        forecast: ``"rates"`` (the public rates and schedules) or ``"ma"`` (a moving average
            of observed requests).
        H, R, window: the knobs (:data:`KNOBS`), integers >= 1.
        scenario: the public config (``rates``); None: from :meth:`set_world` (the evaluator's).
        shortfall_cost: the MILP's price of a request per step not covered, salary units.
        action_cost: its price of a hire or let-go, salary units.
        capacity_scale: a factor on the capacity model's requests a step per person (the
            model is coarse; tuning may correct it).
        calibrate: False (today's model) or True: the capacity times the ratio of repairs
            observed to those the model expects over the busy person-steps (decayed, with a
            prior), the share of facilities operational averaged over ``window`` steps
            (``rates``) instead of read off this step, and (``ma``) the base's workforce
            actions until a full window of requests is seen. The diagnosis that asked for it:
            docs/policies.md, "mpc".
        backlog: False (the MILP covers new requests or pays a shortfall) or True: also a
            fluid queue, requests served up to the productive people's full rate (the capacity
            over the target utilization) and the rest waiting, seeded from the requests waiting
            now (``requesting``), each priced a step at ``backlog_weight`` times the score's
            exchange rate (:data:`BACKLOG_WEIGHT`).
        backlog_weight: that factor (``backlog=True`` only), 0.1 to 100.
        node_limit: HiGHS's branch-and-bound nodes per solve, at most.
        name: the policy's name.
    """

    decisions = AGENTS
    reads_trace = False

    def __init__(self, base: Any, forecast: str = "rates", H: int = DEFAULTS["H"], R: int = DEFAULTS["R"],
                 window: int = DEFAULTS["window"], scenario: ScenarioConfig | None = None,
                 shortfall_cost: float = SHORTFALL_COST, action_cost: float = ACTION_COST,
                 capacity_scale: float = 1.0, node_limit: int = NODE_LIMIT, name: str | None = None,
                 calibrate: bool = False, backlog: bool = False, backlog_weight: float = BACKLOG_WEIGHT):
        if not getattr(base, "compiled", False):
            raise ValueError(f"mpc base {getattr(base, 'name', base)!r} is not a composite of built-in kernels; "
                             "allowed: a compiled composite (a registry composite or tuned file of one)")
        if forecast not in FORECASTS:
            raise ValueError(f"mpc forecast {forecast!r} is not allowed; allowed: {', '.join(FORECASTS)}")
        self.H, self.R, self.window = knob("H", H), knob("R", R), knob("window", window)
        self.base, self.forecast = base, forecast
        self.shortfall_cost = TUNABLE["shortfall_cost"].check(shortfall_cost, "shortfall_cost")
        self.action_cost = TUNABLE["action_cost"].check(action_cost, "action_cost")
        self.capacity_scale = TUNABLE["capacity_scale"].check(capacity_scale, "capacity_scale")
        self.node_limit = knob("node_limit", node_limit)
        if not isinstance(calibrate, (bool, np.bool_)):
            raise ValueError(f"mpc calibrate = {calibrate!r} is not allowed; allowed: True or False")
        self.calibrate = bool(calibrate)
        if not isinstance(backlog, (bool, np.bool_)):
            raise ValueError(f"mpc backlog = {backlog!r} is not allowed; allowed: True or False")
        self.backlog = bool(backlog)
        self.backlog_weight = BACKLOG_TUNABLE["backlog_weight"].check(backlog_weight, "backlog_weight")
        self.name = name or f"mpc-{forecast}"
        self.config = None if scenario is None else require_config(scenario, f"{self.name} scenario=")
        self.timing: dict[str, float] = {}
        self.last: list[Any] = []  # the last solve's SolveResult per environment

    def settings(self) -> dict[str, int]:
        out = {"H": self.H, "R": self.R}
        if self.forecast == "ma" or self.calibrate:
            out["window"] = self.window
        if self.calibrate:
            out["calibrate"] = True
        if self.backlog:
            out["backlog"] = True
        return out

    @property
    def tunable(self) -> dict[str, Param]:
        """What a tuner may search, name -> range (``window`` only for the ``ma`` forecast)."""
        out = {k: p for k, p in TUNABLE.items() if k != "window" or self.forecast == "ma"}
        if self.backlog:
            out.update(BACKLOG_TUNABLE)
        return out

    def params(self) -> dict[str, float | int]:
        """The current value of each tunable parameter."""
        return {k: getattr(self, k) for k in self.tunable}

    def with_params(self, params: dict[str, float | int], name: str | None = None) -> MPC:
        """A copy with some tunable parameters changed; ValueError of one line names a bad name or value."""
        values = self.params()
        for k, v in params.items():
            if k not in self.tunable:
                raise ValueError(f"{self.name} has no tunable parameter {k!r}; allowed: {', '.join(self.tunable)}")
            values[k] = self.tunable[k].check(v, k)
        return MPC(self.base, forecast=self.forecast, scenario=self.config, node_limit=self.node_limit,
                   name=name or self.name, calibrate=self.calibrate,
                   **({"backlog": True} if self.backlog else {}), **values)

    def set_world(self, config: ScenarioConfig) -> None:
        """The world's public parameters (the evaluator calls it before ``reset``); ``rates`` needs them."""
        self.config = require_config(config, f"{self.name}.set_world")

    def reset(self, seeds: int | Sequence[int]) -> None:
        self._seeds = seeds_array(seeds)
        self._started = False

    # -- state from the observations ---------------------------------------------------------------------------
    def _start(self, obs: dict[str, np.ndarray]) -> None:
        B, M, N = obs["facilities"].shape[0], obs["facilities"].shape[1], obs["personnel"].shape[1]
        if len(self._seeds) != B:
            raise RuntimeError(f"{self.name}: reset with {len(self._seeds)} seed(s), observed {B} environment(s)")
        if self.forecast == "rates" and self.config is None:
            raise ValueError(f"{self.name}: the 'rates' forecast needs the world's public config (set_world, as the "
                             "evaluator calls it, or scenario=); allowed without it: mpc-ma")
        self.codes, self.hp, self.pstate = self.base.compiled_plan(self._seeds, M, N)
        self.B, self.M, self.N = B, M, N
        self.ready_at = np.zeros((B, N), dtype=np.int64)  # step onboarding ends
        self.leave_at = np.full((B, N), -1, dtype=np.int64)  # step a notice ends
        self.prev_status = np.full((B, N), EMPTY, dtype=np.int64)
        self.prev_notice = np.zeros((B, N), dtype=np.int64)
        self.prev_down = np.zeros((B, M), dtype=bool)
        self.prev_cell = np.full((B, M, 2), -1, dtype=np.int64)
        self.onsets = np.zeros((B, self.window), dtype=np.float64)  # new requests per step, a ring
        self.fac_onsets = np.zeros((B, M, self.window), dtype=np.float64)
        self.plan = np.zeros((B, self.H), dtype=np.int64)
        self.travel_mean = np.zeros(B)
        self.travel_n = np.zeros(B)
        self.plan_t0 = np.full(B, -(10**9), dtype=np.int64)
        self.up_ring = np.zeros((B, self.window), dtype=np.float64)  # share of facilities operational, a ring
        self.seen_repairs = np.zeros(B)  # decayed repairs observed (calibrate)
        self.busy_steps = np.zeros((B, 3))  # decayed busy person-steps per level (calibrate)
        self.timing = {"steps": 0.0, "act_s": 0.0, "solves": 0.0, "solve_s": 0.0}
        if self.config is not None:
            c = self.config
            self.req_mult = c.request_schedule.multipliers(c.horizon)
            self.churn_mult = c.churn_schedule.multipliers(c.horizon)
        self._started = True

    def _observe(self, obs: dict[str, np.ndarray], t: np.ndarray) -> None:
        status = np.asarray(obs["personnel_status"], dtype=np.int64)
        notice = np.asarray(obs["under_notice"], dtype=np.int64)
        world = np.asarray(obs["world"], dtype=np.float64)
        hd = world[:, W["hire_delay"]].astype(np.int64)
        nd = world[:, W["notice_delay"]].astype(np.int64)
        hired = (status != EMPTY) & (self.prev_status == EMPTY) & (t[:, None] > 0)
        self.ready_at = np.where(hired, (t - 1 + hd)[:, None], self.ready_at)
        noticed = (notice == 1) & (self.prev_notice == 0)
        self.leave_at = np.where(noticed, (t - 1 + nd)[:, None], np.where(status == EMPTY, -1, self.leave_at))
        self.prev_status, self.prev_notice = status, notice
        fac = obs["facilities"]
        active = np.asarray(obs["facility_mask"]) == 1
        down = active & (fac[..., FAC_REQUESTING] > 0.5)
        cell = np.stack([fac[..., FAC_X], fac[..., FAC_Y]], axis=-1).astype(np.int64)
        same = active & (cell == self.prev_cell).all(-1)
        new = down & ~(self.prev_down & same)
        slot = t % self.window
        rows = np.arange(self.B)
        if self.calibrate:
            repaired = self.prev_down & same & ~down  # a request closed at its own facility: a repair
            busy = (status >= TO_FACILITY) & (status <= RETURNING) & (t[:, None] > 0)
            level = np.asarray(obs["personnel"][..., PER_LEVEL], dtype=np.int64)
            self.seen_repairs = self.seen_repairs * CALIBRATION_DECAY + repaired.sum(-1)
            self.busy_steps *= CALIBRATION_DECAY
            for lv in range(3):
                self.busy_steps[:, lv] += (busy & (level == lv)).sum(-1)
            n_act = active.sum(-1)
            self.up_ring[rows, slot] = np.where(n_act > 0, 1.0 - down.sum(-1) / np.maximum(n_act, 1), 1.0)
        self.onsets[rows, slot] = new.sum(-1)
        self.fac_onsets[~same] = 0.0  # a new facility in the slot: forget the old one's requests
        self.fac_onsets[rows, :, slot] = new
        self.prev_down, self.prev_cell = down, np.where(active[..., None], cell, -1)

    # -- the forecast -------------------------------------------------------------------------------------------
    def _demand(self, b: int, t: int, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Forecast new requests per step over the next H steps of environment b."""
        H = self.H
        if self.forecast == "ma":
            seen = min(t + 1, self.window)
            return np.full(H, self.onsets[b].sum() / seen)
        c = self.config
        life = max(c.initial_facilities, 1) * c.churn_interval
        steps = np.minimum(t + np.arange(H), c.horizon)
        n0 = float(np.asarray(obs["facility_mask"])[b].sum())
        keep = math.exp(-1.0 / life)
        arrivals = self.churn_mult[steps] / c.churn_interval
        active = np.empty(H)
        n = n0
        for h in range(H):  # E[active]: survivors plus arrivals (lifetimes memoryless)
            active[h] = n
            n = n * keep + arrivals[min(h + 1, H - 1)]
        down = (obs["facilities"][b, :, FAC_REQUESTING] > 0.5) & (np.asarray(obs["facility_mask"])[b] == 1)
        up = 1.0 - down.sum() / max(n0, 1.0)  # only operational facilities fail
        if self.calibrate:  # the share now swings with the backlog, and a low one (a backlog) planned fewer people
            up = float(self.up_ring[b, : min(t + 1, self.window)].mean())
        return active * up * self.req_mult[steps] / c.request_interval

    def _instance(self, b: int, t: int, obs: dict[str, np.ndarray]) -> StaffingInstance:
        H = self.H
        world = np.asarray(obs["world"], dtype=np.float64)[b]
        status = self.prev_status[b]
        notice = self.prev_notice[b]
        per = obs["personnel"][b]
        level = per[:, PER_LEVEL].astype(np.int64)
        on = status != EMPTY
        steps = t + np.arange(H)
        ready = np.zeros((3, H))
        paid = np.zeros((3, H))
        for p in np.flatnonzero(on):
            lv = level[p]
            if notice[p] == 1:
                paid[lv] += steps < self.leave_at[b, p]
                continue
            paid[lv] += 1.0
            if status[p] == ONBOARDING:
                ready[lv] += steps >= self.ready_at[b, p]
            else:
                ready[lv] += 1.0
        fix = world[[W["fix_novice"], W["fix_mid"], W["fix_expert"]]]
        salary = world[[W["salary_novice"], W["salary_mid"], W["salary_expert"]]]
        speed = max(world[W["speed"]], 1e-9)
        fac = obs["facilities"][b]
        act = np.asarray(obs["facility_mask"])[b] == 1
        homes = per[(on & (notice == 0))][:, [PER_HOME_X, PER_HOME_Y]]
        travel = 0.0
        if act.any() and len(homes):
            f = fac[act]
            d = np.abs(f[:, None, FAC_X] - homes[None, :, 0]) + np.abs(f[:, None, FAC_Y] - homes[None, :, 1])
            travel = float(d.min(axis=1).mean()) / speed
        # the running mean over this episode's solves: the nearest home is farther with fewer people, and a
        # capacity read off the present headcount alone swings the plan (let go, then hire back)
        self.travel_n[b] += 1.0
        self.travel_mean[b] += (travel - self.travel_mean[b]) / self.travel_n[b]
        T = world[W["service_time"]] + 2.0 * self.travel_mean[b]
        cap = self.capacity_scale * (world[W["target_utilization"]] * fix / max(T, 1e-9))
        if self.calibrate:  # the model's rate per busy person-step measured: about 1.35 times too low on paper-64
            # summed in order, not by a BLAS dot: OpenBLAS picks its kernel by the CPU, and its AVX-512 ddot rounds the
            # last bit of a 3-term sum otherwise than the in-order sum about one time in four; a 1-ulp capacity flips
            # a tie between two plans of equal cost (docs/hindsight.md, "One piece of the suite ...")
            rate = fix / max(T, 1e-9)
            expected = 0.0
            for lv in range(rate.shape[0]):
                expected += float(self.busy_steps[b, lv]) * float(rate[lv])
            cap = cap * (self.seen_repairs[b] + PRIOR_REPAIRS) / (expected + PRIOR_REPAIRS)
        queue = {}
        if self.backlog:  # the requests waiting now (open, nobody assigned), priced at the score's exchange rate
            rate = world[W["max_personnel"]] * salary.max() / max(float(act.sum()), 1.0)
            queue = {"backlog0": float((np.asarray(obs["requesting"])[b] == 1).sum()),
                     "backlog_cost": self.backlog_weight * rate,  # served at the full rate: all busy, not the target
                     "service": cap / max(world[W["target_utilization"]], 1e-9)}
        return StaffingInstance(demand=self._demand(b, t, obs), capacity=cap, salary=salary, ready=ready, paid=paid,
                                hire_delay=int(world[W["hire_delay"]]), notice_delay=int(world[W["notice_delay"]]),
                                max_headcount=int(world[W["max_personnel"]]),
                                min_headcount=int(world[W["min_personnel"]]), shortfall_cost=self.shortfall_cost,
                                action_cost=self.action_cost, **queue)

    def _positioning(self, b: int, obs: dict[str, np.ndarray], out: np.ndarray) -> None:
        fac = obs["facilities"][b]
        act = np.asarray(obs["facility_mask"])[b] == 1
        if not act.any():
            return
        world = np.asarray(obs["world"], dtype=np.float64)[b]
        reach = 2.0 * world[W["heat_sigma"]]
        on = (self.prev_status[b] != EMPTY) & (self.prev_notice[b] == 0)
        homes = obs["personnel"][b][on][:, [PER_HOME_X, PER_HOME_Y]]
        if self.forecast == "ma":
            demand = self.fac_onsets[b].sum(-1) + 1.0 / self.window  # a facility's own requests, smoothed
        else:
            demand = np.ones(self.M)  # memoryless failures and lifetimes: every active facility alike
        near = np.zeros(self.M)
        if len(homes):
            d = np.abs(fac[:, None, FAC_X] - homes[None, :, 0]) + np.abs(fac[:, None, FAC_Y] - homes[None, :, 1])
            near = (d <= reach).sum(axis=1)
        per_person = np.where(act, demand / (1.0 + near), 0.0)
        out[0] = per_person / per_person.max()
        inv = np.where(act, (1.0 + near) / demand, 0.0)
        out[1] = inv / inv.max()

    # -- the protocol -------------------------------------------------------------------------------------------
    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        start = time.perf_counter()
        t = np.broadcast_to(np.asarray(obs["t"], dtype=np.int64), (obs["facilities"].shape[0],))
        if not self._started or (t[0] == 0 and self.timing["steps"] > 0):
            self._start(obs)
        self._observe(obs, t)
        B, M, N = self.B, self.M, self.N
        d = np.full((B, M), N, dtype=np.int64)
        w = np.zeros(B, dtype=np.int64)
        p = np.zeros((B, 2, M), dtype=np.float64)
        K.act_batch(as_obs(obs), self.pstate, self.codes, self.hp, d, w, p, np.ascontiguousarray(t))
        mask = np.asarray(obs["workforce_mask"])
        self.last = [None] * B if len(self.last) != B else self.last
        for b in range(B):
            tb = int(t[b])
            if self.calibrate and self.forecast == "ma" and tb + 1 < self.window:
                continue  # the base's workforce actions until a full window: at step 0 it saw no request and let go
            if tb - self.plan_t0[b] >= min(self.R, self.H):
                s0 = time.perf_counter()
                res = plan_staffing(self._instance(b, tb, obs), node_limit=self.node_limit, block=BLOCK)
                self.timing["solves"] += 1
                self.timing["solve_s"] += time.perf_counter() - s0
                self.plan[b] = res.solution
                self.plan_t0[b] = tb
                self.last[b] = res
            a = int(self.plan[b, tb - self.plan_t0[b]])
            w[b] = a if mask[b, a] else 0
            if w[b] != 0:
                self._positioning(b, obs, p[b])
        self.timing["steps"] += 1
        self.timing["act_s"] += time.perf_counter() - start
        return {"dispatch": d, "workforce": w, "positioning": p}


def make(base: Any, forecast: str, name: str | None = None, **knobs: Any) -> MPC:
    """An :class:`MPC` of ``base`` with the ``forecast`` kind, knobs overriding the defaults."""
    return MPC(base, forecast=forecast, name=name, **knobs)


__all__ = ["BACKLOG_WEIGHT", "DEFAULTS", "FORECASTS", "KNOBS", "MPC", "NODE_LIMIT", "PRESET_OPTIONS", "TUNABLE",
           "knob", "make"]
