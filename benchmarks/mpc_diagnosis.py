"""Why the MPC churns: what its MILP predicts at each re-solve against what the simulator then does (issue #53).

Plays ``mpc-ma`` and ``mpc-rates`` (and any ``--variant``, an MPC knob set) on public seeds of
training-split worlds and, at every re-solve, keeps the plan's forecast demand, coverage
(``capacity @ productive``), productive people and payroll per step of its horizon. Over the
same steps it reads the simulator's state: new requests, repairs, productive people (on the
payroll, onboarded, not under notice), busy people, open requests, downtime and utilization.
Then it prints, per policy and world:

- ``demand``: forecast new requests a step over the ``R`` steps played, against those observed;
- ``svc/busy``: the model's repairs per busy person-step (``fix_l / T``, at the plan's mix),
  against the observed repairs per busy person-step (traveling, servicing or returning);
- ``util``: the model's target utilization against the observed busy share of productive people;
- ``prod``: productive people the plan expected R and H steps ahead, against those observed;
- ``need``: the productive people the model asks for (demand over capacity) and the size of
  each solve's swing in it, the churn's cause when it swings by more than the lags can absorb;
- ``backlog`` (``backlog=True`` only): the requests the plan expects waiting over the ``R`` steps
  played, against those waiting in the simulator (open, nobody assigned);
- hires and let-goes an episode, against ``solver-tuned-train``'s, and the mean NSW;
- ``cpu``: the policy's CPU time per environment-step (``time.process_time`` around ``act``,
  one thread: run it with ``NUMBA_NUM_THREADS=1``).

Any registered MPC may be named in ``--policies`` (``mpc-ma-calibrated``, ``mpc-rates-backlog``),
with its own knobs.

Public seeds only (1000-1049; never the test seeds 0-49). Run:

    python benchmarks/mpc_diagnosis.py --scenarios paper-64-v1 nonstationary-v1 --seeds 1000 1001 1002
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from wfbench.policies.lookahead import MPC
from wfbench.policies.lookahead.mpc import BLOCK

from wfbench import policies
from wfbench.core.simulator import Simulator
from wfbench.core.state import (
    C_REPAIRS,
    C_REQUESTS,
    EMPTY,
    K_AFD,
    K_NSW,
    K_PUR,
    ONBOARDING,
    RETURNING,
    TO_FACILITY,
)
from wfbench.harness.budget import machine
from wfbench.harness.runner import public_world, run_batch
from wfbench.scenarios.resolve import resolve_scenario


def play(pol: MPC, config, seeds):
    """One batch of ``pol``, step by step; per-step observations and per-solve plans."""
    sim = Simulator(config, seeds)
    obs = sim.reset()
    pol.set_world(public_world(sim.config))
    pol.reset(sim.seeds)
    B, T = sim.B, config.horizon
    seen = {k: np.zeros((B, T)) for k in ("req", "rep", "prod", "busy", "open", "wait", "afd", "pur", "head")}
    solves: list[dict] = []
    last_c = sim.state.counters.copy()
    while not sim.done:
        t = int(sim.state.t[0])
        c0 = time.process_time()
        out = pol.act(obs)
        pol.cpu_s = getattr(pol, "cpu_s", 0.0) + time.process_time() - c0
        for b in range(B):
            if pol.plan_t0[b] == t and pol.last[b] is not None:
                d = pol.last[b].detail
                solves.append({"b": b, "t": t, "demand": pol._last_demand[b].copy(),
                               "coverage": np.asarray(d["coverage"]), "prod": d["productive"].sum(0),
                               "pay": d["payroll"].sum(0), "cap": pol._last_cap[b].copy(),
                               "backlog": np.asarray(d.get("backlog", np.full(len(d["shortfall"]), np.nan))),
                               "optimal": pol.last[b].status == "optimal", "solve_s": pol.last[b].solve_time_s,
                               "hires": int(d["hires"][:, : -(-pol.R // BLOCK)].sum()),
                               "letgo": int(d["letgo"][:, : -(-pol.R // BLOCK)].sum())})
        sim.step(out)
        obs = sim.observe()
        s = sim.state
        c = s.counters
        st = s.per_status
        on = (st != EMPTY) & (st != ONBOARDING) & (s.per_leave < 0)
        seen["req"][:, t] = c[:, C_REQUESTS] - last_c[:, C_REQUESTS]
        seen["rep"][:, t] = c[:, C_REPAIRS] - last_c[:, C_REPAIRS]
        seen["prod"][:, t] = on.sum(1)
        seen["busy"][:, t] = (on & (st >= TO_FACILITY) & (st <= RETURNING)).sum(1)
        seen["open"][:, t] = (s.fac_active & s.fac_down).sum(1)
        seen["wait"][:, t] = (s.fac_active & s.fac_down & (s.fac_assigned < 0)).sum(1)
        seen["afd"][:, t] = s.last[:, K_AFD]
        seen["pur"][:, t] = s.last[:, K_PUR]
        seen["head"][:, t] = (st != EMPTY).sum(1)
        last_c = c.copy()
    return sim, seen, solves


def se(x: np.ndarray) -> float:
    return float(np.std(x, ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")


class Recording(MPC):
    """An MPC that keeps each solve's demand forecast and capacities (read-only: the plan is unchanged)."""

    def _instance(self, b, t, obs):
        inst = super()._instance(b, t, obs)
        if not hasattr(self, "_last_demand") or len(self._last_demand) != self.B:
            self._last_demand, self._last_cap = [None] * self.B, [None] * self.B
        self._last_demand[b], self._last_cap[b] = inst.demand, inst.capacity
        return inst


def recording(name: str, **knobs) -> Recording:
    src = policies.get(name)
    values = {**src.params(), **knobs}
    keep = {"calibrate": src.calibrate, **({"backlog": True} if getattr(src, "backlog", False) else {})}
    return Recording(src.base, forecast=src.forecast, node_limit=src.node_limit, name=name, **{**keep, **values})


def summarize(name, config, seeds, sim, seen, solves, base_counters, base_nsw, wall, R, trace=False):
    rows = []
    for s in solves:
        b, t0 = s["b"], s["t"]
        H = len(s["demand"])
        end = min(t0 + H, config.horizon)
        r_end = min(t0 + R, config.horizon)
        obs_req = seen["req"][b, t0:r_end].mean()
        obs_req_h = seen["req"][b, t0:end].mean()
        busy = seen["busy"][b, t0:r_end].sum()
        rep = seen["rep"][b, t0:r_end].sum()
        prod = seen["prod"][b, t0:r_end]
        cov = s["coverage"][: r_end - t0]
        pp = s["prod"][: r_end - t0]
        # the model's repairs per busy person-step at the plan's productive mix: coverage / productive / target
        tu = float(sim.config.target_utilization)
        model_rate = float(cov.sum() / max(pp.sum(), 1e-9) / tu)
        rows.append({
            "fc": s["demand"][: r_end - t0].mean(), "fc_h": s["demand"][: end - t0].mean(), "req": obs_req,
            "req_h": obs_req_h, "m_rate": model_rate, "o_rate": rep / busy if busy else np.nan,
            "o_util": busy / max(prod.sum(), 1), "p_pred_R": s["prod"][min(R, H) - 1],
            "p_obs_R": seen["prod"][b, min(t0 + R - 1, config.horizon - 1)],
            "p_pred_H": s["prod"][end - t0 - 1], "p_obs_H": seen["prod"][b, end - 1],
            "need": float(s["demand"][: end - t0].mean() / max(model_rate * tu, 1e-9)),
            "short": float(np.maximum(s["demand"] - s["coverage"], 0).mean()),
            "open": seen["open"][b, t0:r_end].mean(), "h": s["hires"], "l": s["letgo"], "b": b,
            "q_plan": float(np.mean(s["backlog"][: r_end - t0])), "q_obs": seen["wait"][b, t0:r_end].mean()})
    f = {k: np.array([r[k] for r in rows], dtype=float) for k in rows[0]}
    need_swing = []
    for b in range(len(seeds)):
        n = f["need"][f["b"] == b]
        need_swing.append(np.abs(np.diff(n)).mean() if len(n) > 1 else np.nan)
    c = sim.counters()
    nsw = sim.state.totals[:, K_NSW] / np.maximum(sim.state.t, 1)
    print(f"\n== {name} on {config.name}, seeds {list(seeds)}: {len(solves)} solves, {wall:.0f} s")
    print(f"  demand a step (R played):   forecast {f['fc'].mean():.3f}  observed {f['req'].mean():.3f}  "
          f"(over H: {f['fc_h'].mean():.3f} vs {f['req_h'].mean():.3f}); |error| a solve "
          f"{np.abs(f['fc'] - f['req']).mean():.3f}")
    print(f"  repairs per busy person-step: model {np.nanmean(f['m_rate']):.4f}  observed "
          f"{np.nanmean(f['o_rate']):.4f}  (ratio {np.nanmean(f['o_rate']) / np.nanmean(f['m_rate']):.2f})")
    print(f"  busy share of productive:   model {sim.config.target_utilization:.2f}  observed "
          f"{f['o_util'].mean():.3f};  utilization KPI {seen['pur'].mean():.3f}, downtime KPI "
          f"{seen['afd'].mean():.3f}, open requests {f['open'].mean():.2f}")
    print(f"  productive people:          plan at +R {f['p_pred_R'].mean():.1f} vs observed "
          f"{f['p_obs_R'].mean():.1f}; plan at +H {f['p_pred_H'].mean():.1f} vs observed {f['p_obs_H'].mean():.1f}")
    print(f"  people the model needs:     {f['need'].mean():.1f} (swing between solves {np.nanmean(need_swing):.2f}); "
          f"planned shortfall a step {f['short'].mean():.3f}")
    print(f"  hires/let-goes an episode:  {c['hires'].mean():.1f} / {c['releases'].mean():.1f}  "
          f"(the plans' for the steps played: {f['h'].sum() / len(seeds):.1f} / {f['l'].sum() / len(seeds):.1f}); "
          f"base {base_counters['hires'].mean():.1f} / {base_counters['releases'].mean():.1f}")
    if np.isfinite(f["q_plan"]).any():
        print(f"  backlog (waiting) over R:   plan {f['q_plan'].mean():.2f} vs observed {f['q_obs'].mean():.2f}; "
              f"|error| a solve {np.abs(f['q_plan'] - f['q_obs']).mean():.2f}")
    steps = config.horizon * len(seeds)
    print(f"  cpu per env-step:           {1e3 * getattr(sim, 'cpu_s', np.nan) / steps:.2f} ms; solves not optimal "
          f"(node limit) {sum(not s['optimal'] for s in solves)} of {len(solves)}, the longest "
          f"{max(s['solve_s'] for s in solves):.2f} s wall")
    print(f"  NSW {nsw.mean():.4f} ({', '.join(f'{v:.3f}' for v in nsw)}); base {base_nsw.mean():.4f}; "
          f"paired diff {np.mean(nsw - base_nsw):+.4f} ± {se(nsw - base_nsw):.4f}")
    if trace:
        print(f"    t    fc    req  need  prod_obs  busy%  open  hires letgo  (seed {seeds[0]})")
        for r, s in zip(rows, solves, strict=True):
            if r["b"] == 0:
                print(f"  {s['t']:4d} {r['fc']:.3f} {r['req']:.3f} {r['need']:5.1f} {r['p_obs_R']:6.0f} "
                      f"{100 * r['o_util']:6.0f} {r['open']:5.1f} {r['h']:5d} {r['l']:5d}")
    return f, nsw


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=["paper-64-v1"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1000, 1001, 1002])
    ap.add_argument("--policies", nargs="*", default=["mpc-ma", "mpc-rates"])
    ap.add_argument("--variant", action="append", default=[],
                    help="NAME:KEY=VALUE,... an MPC knob set on top of NAME (e.g. mpc-ma:capacity_scale=0.8)")
    ap.add_argument("--trace", action="store_true", help="also print each solve of the first seed")
    ap.add_argument("--horizon", type=int, default=None, help="cut the episode (default: the world's)")
    a = ap.parse_args()
    if any(s < 1000 for s in a.seeds):
        raise SystemExit("mpc_diagnosis: public seeds only (1000-1049); the test seeds 0-49 are never played here")
    print(f"machine: {machine()}")
    for scen in a.scenarios:
        config = resolve_scenario(scen)
        if a.horizon:
            config = config.replace(horizon=a.horizon)
        base = run_batch(policies.get("solver-tuned-train"), config, a.seeds)
        print(f"\n## {scen}: solver-tuned-train NSW {base.means['nsw'].mean():.4f}, hires/let-goes "
              f"{base.counters['hires'].mean():.1f} / {base.counters['releases'].mean():.1f}")
        todo = [(n, n, {}) for n in a.policies]
        for v in a.variant:
            name, _, rest = v.partition(":")
            knobs: dict = {}
            params = policies.get(name).params()
            for kv in filter(None, rest.split(",")):
                k, _, val = kv.partition("=")
                knobs[k] = val == "True" if val in ("True", "False") else type(params.get(k, 0.0))(float(val))
            todo.append((v, name, knobs))
        for label, name, knobs in todo:
            pol = recording(name, **knobs)
            t0 = time.perf_counter()
            sim, seen, solves = play(pol, config, a.seeds)
            sim.cpu_s = pol.cpu_s  # the policy's CPU seconds, carried to the summary
            summarize(label, config, a.seeds, sim, seen, solves, base.counters, base.means["nsw"],
                      time.perf_counter() - t0, pol.R, a.trace)


if __name__ == "__main__":
    main()
