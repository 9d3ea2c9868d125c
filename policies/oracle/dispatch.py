"""The dispatch oracle's candidates: small changes to the nearest-first dispatch that hindsight suggests.

The oracle knows each open request's next repair outcome (the draw of (slot, request, visit) is
a pure function of the seed, :mod:`wfbench.core.rng`). Its candidates are the base
nearest-first dispatch (always first) and, for each of at most ``max_requests`` requests the
base serves first, holding back the person sent, the nearest person who would fix it, and the
runner-up, each swapped in. Each is scored by an exact roll-forward of the shadow
(:mod:`wfbench.policies.kernels.forward`) under the base; the base wins ties
(``docs/hindsight.md``, "Dispatch oracle").
"""

from __future__ import annotations

import numpy as np

from wfbench.core.rng import STREAM_REPAIR, uniform


def next_visit_fixes(key: np.uint64, f: int, request: int, visit: int, fix_prob: np.ndarray) -> np.ndarray:
    """(3,) bool: whether the next visit to request ``request`` of slot ``f`` fixes the fault, by level."""
    u = uniform(key, STREAM_REPAIR, f, request, visit)
    return u < fix_prob


def _swap_in(base: np.ndarray, f: int, q: int, N: int) -> np.ndarray:
    """``base`` with person q sent to facility f; the request q served in ``base`` gets f's person instead."""
    row = base.copy()
    old = row[f]
    where = np.flatnonzero(row == q)
    for g in where:
        row[g] = old if old < N else N
    row[f] = q
    return row


def dispatch_candidates(base: np.ndarray, requesting: np.ndarray, free: np.ndarray, fac_xy: np.ndarray,
                        per_xy: np.ndarray, levels: np.ndarray, fixes: dict[int, np.ndarray],
                        max_requests: int) -> list[np.ndarray]:
    """The candidate dispatch rows (M,) of one environment, the base first, without duplicates.

    Args:
        base: (M,) the nearest-first dispatch (N = nobody).
        requesting: (M,) 1 where a request is open and unassigned.
        free: (N,) 1 where a person may be dispatched.
        fac_xy: (M, 2) facility cells.
        per_xy: (N, 2) current positions of the people.
        levels: (N,) their levels.
        fixes: facility slot -> (3,) bool, whether the next visit by each level fixes it.
        max_requests: how many requests get alternatives.
    """
    N = free.shape[0]
    out = [base]
    seen = {base.tobytes()}

    def add(row: np.ndarray) -> None:
        key = row.tobytes()
        if key not in seen:
            seen.add(key)
            out.append(row)

    reqs = np.flatnonzero(requesting)
    people = np.flatnonzero(free)
    if reqs.size == 0 or people.size == 0:
        return out
    served = [f for f in reqs if base[f] < N]
    order = served + [f for f in reqs if base[f] >= N]
    for f in order[:max_requests]:
        d = np.abs(per_xy[people, 0] - fac_xy[f, 0]) + np.abs(per_xy[people, 1] - fac_xy[f, 1])
        rank = people[np.argsort(d, kind="stable")]
        if base[f] < N:
            hold = base.copy()
            hold[f] = N
            add(hold)
        fx = fixes.get(int(f))
        if fx is not None:
            fixers = [q for q in rank if fx[levels[q]]]
            if fixers:
                add(_swap_in(base, f, int(fixers[0]), N))
        others = [q for q in rank if q != base[f]]
        if others:
            add(_swap_in(base, f, int(others[0]), N))
    return out
