"""How large k must be: the sparse solves against the dense ones on instances met along real episodes (issue #35).

The dense ``solver`` composite is stepped through the Python API; every ``--every`` steps
the instances its two solves meet are taken from the observation and solved both ways:

- dispatch: the open requests x the dispatchable people, costs as the ``assignment`` rule
  (:func:`wfbench.policies.kernels.assignment_costs`, default hyper-parameters). Dense:
  :func:`wfbench.solvers.lap.lap_min`; sparse: :func:`wfbench.solvers.lap.lap_sparse` on
  each request's k nearest people. Reported: the share of instances where the sparse
  optimum equals the dense optimum (same total cost; requests all served).
- p-median: the active sites as clients and candidates, ``p = retained headcount + 1``,
  weights ``demand_floor`` plus the downtime share of the observed demand (the request-rate
  share needs the policy's history, so this is the rule's instance up to that term).
  Dense: greedy + swap local search (:mod:`wfbench.solvers.facility_location`); sparse:
  :func:`wfbench.solvers.facility_location.p_median_sparse` on each client's k nearest sites.
  Reported: the mean and worst relative excess of the sparse medians' dense objective over
  the dense heuristic's (negative: the sparse search found better), the share of identical
  median sets, and the milliseconds per solve of each.

Usage (one thread: seconds on ``large``, about a minute on ``city``)::

    python benchmarks/sparse_k.py --scenario large --steps 200 --every 20 --ks 2,4,8,16
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from wfbench.policies import get
from wfbench.policies import kernels as K
from wfbench.policies.protocol import as_obs
from wfbench.solvers.facility_location import greedy_open, local_search, p_median_sparse
from wfbench.solvers.lap import knn_manhattan, lap_min, lap_sparse

from wfbench import Simulator
from wfbench.core.observe import FAC_DOWNTIME, FAC_X, FAC_Y, PER_X, PER_Y
from wfbench.harness.budget import machine, machine_line
from wfbench.scenarios.resolve import resolve_scenario


def dispatch_instance(O, hp):
    reqs, people = K.open_requests_and_free_people(0, O)
    if reqs.size == 0 or people.size == 0:
        return None
    C = K.assignment_costs(0, O, hp, reqs, people)
    xy_r = O.facilities[0][reqs][:, [FAC_X, FAC_Y]]
    xy_p = O.personnel[0][people][:, [PER_X, PER_Y]]
    return C, xy_r, xy_p


def dense_dispatch(C):
    nr, npl = C.shape
    W = C if nr <= npl else C.T.copy()
    c4r = np.empty(W.shape[0], dtype=np.int64)
    return lap_min(W, c4r)


def sparse_dispatch(C, xy_r, xy_p, k):
    nr, npl = C.shape
    k = min(k, npl)
    idx = np.empty((nr, k), dtype=np.int64)
    dd = np.empty((nr, k))
    knn_manhattan(xy_r[:, 0].copy(), xy_r[:, 1].copy(), xy_p[:, 0].copy(), xy_p[:, 1].copy(), k, idx, dd)
    cost = np.take_along_axis(C, idx, axis=1)
    big = 1.0 + cost.max(axis=1).sum()
    c4r = np.empty(nr, dtype=np.int64)
    total = lap_sparse(npl, np.arange(nr + 1, dtype=np.int64) * k, idx.ravel().copy(), cost.ravel().copy(),
                       np.full(nr, big), c4r)
    served = int((c4r >= 0).sum())
    return total - (nr - served) * big, served


def pmedian_instance(O, hp):
    sites = np.flatnonzero(O.facility_mask[0] == 1)
    if sites.size < 2:
        return None
    down = O.facilities[0][sites][:, FAC_DOWNTIME]
    w = hp[K.HP_FLOOR] + ((1.0 - hp[K.HP_REQW]) * down / down.max() if down.max() > 0 else 0.0)
    xy = O.facilities[0][sites][:, [FAC_X, FAC_Y]]
    h = int(((O.personnel_mask[0] == 1) & (O.under_notice[0] == 0)).sum())
    return xy, np.asarray(w, dtype=np.float64) * np.ones(sites.size), min(h + 1, sites.size)


def objective(C, is_open):
    return float(C[is_open].min(axis=0).sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="large")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--ks", default="2,4,8,16")
    args = ap.parse_args()
    ks = [int(k) for k in args.ks.split(",")]
    print(f"machine: {machine_line(machine())}; {args.scenario} seed {args.seed}, steps 0-{args.steps - 1} "
          f"every {args.every}", flush=True)
    sim = Simulator(resolve_scenario(args.scenario), [args.seed])
    sim.reset()
    pol = get("solver")
    pol.reset([args.seed])
    hp = np.array([K.HP_DEFAULTS[f] for f in K.HP_FIELDS])
    disp = {k: [] for k in ks}
    pm = {k: [] for k in ks}
    pm_dense_ms = []
    n_disp = 0
    obs = sim.observe()
    for t in range(args.steps):
        if t % args.every == 0:
            O = as_obs(obs)
            inst = dispatch_instance(O, hp)
            if inst is not None:
                n_disp += 1
                ref = dense_dispatch(inst[0])
                for k in ks:
                    total, served = sparse_dispatch(*inst, k)
                    disp[k].append(served == min(inst[0].shape) and abs(total - ref) <= 1e-9 * max(1.0, abs(ref)))
            inst = pmedian_instance(O, hp)
            if inst is not None:
                xy, w, p = inst
                C = np.abs(xy[:, None, :] - xy[None, :, :]).sum(-1) * w[None, :]
                t0 = time.perf_counter()
                is_open = greedy_open(C, np.zeros(len(w)), p)
                local_search(C, np.zeros(len(w)), is_open, p, 1000, 1e-9)
                pm_dense_ms.append(1e3 * (time.perf_counter() - t0))
                ref = objective(C, is_open)
                for k in ks:
                    t0 = time.perf_counter()
                    kk = min(k + 1, len(w))
                    idx = np.empty((len(w), kk), dtype=np.int64)
                    dd = np.empty((len(w), kk))
                    knn_manhattan(xy[:, 0].copy(), xy[:, 1].copy(), xy[:, 0].copy(), xy[:, 1].copy(), kk, idx, dd)
                    kc = min(k, len(w))
                    far = w * dd[:, kc] if kk > kc else np.full(len(w), np.inf)
                    sp_open, _ = p_median_sparse(len(w), idx[:, :kc].copy(), dd[:, :kc] * w[:, None],
                                                 np.full(len(w), kc, dtype=np.int64), far, p, 1000, 1e-9)
                    ms = 1e3 * (time.perf_counter() - t0)
                    excess = (objective(C, sp_open) - ref) / max(ref, 1e-12)
                    pm[k].append((excess, bool((sp_open == is_open).all()), ms))
        sim.step(pol.act(obs))
        obs = sim.observe()
    print(f"dispatch instances: {n_disp}; p-median instances: {len(pm_dense_ms)}, dense "
          f"{np.mean(pm_dense_ms):.2f} ms per solve")
    print(f"{'k':>4s} {'dispatch = dense':>17s} {'p-median excess mean':>21s} {'worst':>9s} {'same medians':>13s} "
          f"{'ms/solve':>9s}")
    for k in ks:
        e = np.array([x[0] for x in pm[k]]) if pm[k] else np.zeros(1)
        same = np.mean([x[1] for x in pm[k]]) if pm[k] else float("nan")
        ms = np.mean([x[2] for x in pm[k]]) if pm[k] else float("nan")
        print(f"{k:4d} {np.mean(disp[k]) if disp[k] else float('nan'):17.1%} {e.mean():+21.4%} {e.max():+9.4%} "
              f"{same:13.1%} {ms:9.2f}", flush=True)


if __name__ == "__main__":
    main()
