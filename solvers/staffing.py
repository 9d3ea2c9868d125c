"""Queueing answers to "how many people do we need".

The service system is read as an M/M/c queue with offered load ``R = lambda * E[S]``
people-busy. :func:`erlang_c` is the probability that a request waits (the stable Erlang-B
recursion), :func:`square_root_staffing` staffs ``c = ceil(R + beta * sqrt(R))`` (``beta`` from a
waiting target through Halfin-Whitt, or ``c = ceil(R / rho)`` for a utilization target), and
:func:`job_duration` builds ``E[S]`` from travel, service and geometric revisits. The formulas:
``docs/solvers.md``, "Staffing".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from wfbench.solvers.result import SolverInputError


def _positive(name: str, v: float, *, zero_ok: bool = False) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise SolverInputError(f"{name} = {v!r} is not a number") from None
    if not math.isfinite(x) or x < 0 or (x == 0 and not zero_ok):
        allowed = ">= 0" if zero_ok else "> 0"
        raise SolverInputError(f"{name} = {v!r} is not allowed; allowed: a finite number {allowed}")
    return x


def erlang_b(servers: int, offered_load: float) -> float:
    """Blocking probability of M/M/c/c (Erlang B)."""
    c = _servers(servers)
    a = _positive("offered_load", offered_load, zero_ok=True)
    b = 1.0
    for k in range(1, c + 1):
        b = a * b / (k + a * b)
    return b


def _servers(servers: int) -> int:
    if isinstance(servers, bool) or not isinstance(servers, int | np.integer) or servers < 0:
        raise SolverInputError(f"servers = {servers!r} is not allowed; allowed: an integer >= 0")
    return int(servers)


def erlang_c(servers: int, offered_load: float) -> float:
    """Probability that an arriving request waits (M/M/c, Erlang C); 1.0 when unstable."""
    c = _servers(servers)
    a = _positive("offered_load", offered_load, zero_ok=True)
    if a == 0.0:
        return 0.0
    if a >= c:
        return 1.0
    b = erlang_b(c, a)
    return c * b / (c - a * (1.0 - b))


def mean_wait(servers: int, offered_load: float, mean_duration: float) -> float:
    """Mean waiting time in the M/M/c queue, in the units of ``mean_duration`` (inf when unstable)."""
    c = _servers(servers)
    a = _positive("offered_load", offered_load, zero_ok=True)
    s = _positive("mean_duration", mean_duration)
    if a >= c:
        return math.inf
    return erlang_c(c, a) * s / (c - a)


def halfin_whitt_beta(wait_probability: float) -> float:
    """The safety factor beta with ``1 / (1 + beta Phi(beta) / phi(beta)) = wait_probability``."""
    alpha = float(wait_probability)
    if not 0.0 < alpha < 1.0:
        raise SolverInputError(f"target_wait_prob = {wait_probability!r} is not allowed; allowed: 0 < alpha < 1")
    # imported here: scipy.stats costs ~1 s of import, and the compiled policies that
    # import this module never call this function
    from scipy.optimize import brentq
    from scipy.stats import norm

    f = lambda b: 1.0 / (1.0 + b * norm.cdf(b) / norm.pdf(b)) - alpha
    if f(8.0) > 0.0:  # alpha below ~1e-15: beyond double precision
        raise SolverInputError(f"target_wait_prob = {alpha!r} is too small to reach; allowed: alpha > 1e-15")
    return float(brentq(f, 1e-12, 8.0, xtol=1e-12))


def job_duration(
    travel: float,
    service: float,
    fix_prob: float | Sequence[float],
    level_mix: Sequence[float] | None = None,
    return_trip: bool = True,
) -> float:
    """Expected person-steps one request takes: ``visits * (travel out + service + travel back)``.

    ``fix_prob`` is the probability a visit fixes the fault: one number, or one per
    level with ``level_mix`` the share of visits by each level (the mean fix
    probability is then ``sum mix_l q_l``; a request needs ``1 / q`` visits on average).
    """
    t = _positive("travel", travel, zero_ok=True)
    s = _positive("service", service)
    q = np.atleast_1d(np.asarray(fix_prob, dtype=np.float64))
    if q.ndim != 1 or not np.isfinite(q).all() or (q <= 0).any() or (q > 1).any():
        raise SolverInputError(f"fix_prob = {fix_prob!r} is not allowed; allowed: probabilities in (0, 1]")
    if level_mix is None:
        if q.size != 1:
            raise SolverInputError("fix_prob has one value per level: pass level_mix with as many shares")
        qbar = float(q[0])
    else:
        w = np.asarray(level_mix, dtype=np.float64)
        if w.shape != q.shape or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
            raise SolverInputError(
                f"level_mix = {level_mix!r} is not allowed; allowed: {q.size} shares >= 0, not all 0"
            )
        qbar = float((w / w.sum()) @ q)
    per_visit = t * (2.0 if return_trip else 1.0) + s
    return per_visit / qbar


@njit(cache=True)
def sqrt_staffing_servers(offered_load, beta):
    """``ceil(R + beta * sqrt(R))``, compiled so simulation kernels can call it (R >= 0, beta >= 0)."""
    return int(math.ceil(offered_load + beta * math.sqrt(offered_load) - 1e-12))


@dataclass(frozen=True)
class StaffingPlan:
    servers: int  # the rule's headcount
    offered_load: float  # R = arrival_rate * mean_duration
    utilization: float  # R / servers
    wait_probability: float  # Erlang C at `servers`
    beta: float | None  # safety factor used (None for the utilization rule)
    rule: str  # "beta", "wait-probability" or "utilization"
    erlang_servers: int | None = None  # smallest c meeting the wait target exactly (wait rule only)


def square_root_staffing(
    arrival_rate: float,
    mean_duration: float,
    *,
    beta: float | None = None,
    target_wait_prob: float | None = None,
    target_utilization: float | None = None,
    min_servers: int = 1,
) -> StaffingPlan:
    """Headcount for a request rate and mean job duration; give exactly one of the three targets."""
    lam = _positive("arrival_rate", arrival_rate, zero_ok=True)
    s = _positive("mean_duration", mean_duration)
    given = [k for k, v in (("beta", beta), ("target_wait_prob", target_wait_prob),
                            ("target_utilization", target_utilization)) if v is not None]
    if len(given) != 1:
        raise SolverInputError(
            f"give exactly one of beta, target_wait_prob, target_utilization; got {given or 'none'}")
    min_servers = _servers(min_servers)
    R = lam * s
    erlang_servers = None
    if target_utilization is not None:
        rho = float(target_utilization)
        if not 0.0 < rho <= 1.0:
            raise SolverInputError(f"target_utilization = {target_utilization!r} is not allowed; allowed: 0 < rho <= 1")
        c = math.ceil(R / rho - 1e-12)
        b, rule = None, "utilization"
    else:
        if target_wait_prob is not None:
            b = halfin_whitt_beta(target_wait_prob)
            rule = "wait-probability"
            erlang_servers = max(math.floor(R) + 1, 1) if R > 0 else 0
            while erlang_servers > 0 and erlang_c(erlang_servers, R) > target_wait_prob:
                erlang_servers += 1
        else:
            b = _positive("beta", beta, zero_ok=True)
            rule = "beta"
        c = sqrt_staffing_servers(R, b)
    c = max(int(c), min_servers)
    util = R / c if c > 0 else 0.0
    return StaffingPlan(c, R, util, erlang_c(c, R), b, rule, erlang_servers)
