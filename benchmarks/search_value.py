"""How good is the network's critic as the end of a search's future? (issue #52, ``search-scalefree-general``)

The network plays whole episodes in its greedy mode (as in the search's futures); at every step s
it records the critic's value V_s of the observation and the NSW reward, and G_s, the NSW summed
from s to the end of the episode (the part of the episode objective a future cut at s leaves
out). A search compares candidates whose futures end at the same step, so only the critic's
ranking of states at one step matters: the slope b of G on V within a step (step fixed effects)
is fitted on training seeds per band of steps left (the critic is discounted, gamma 0.995, and
does not see the end coming, so its scale shrinks near the end), and its error is measured on
public seeds against the baseline that knows only the step (each step's mean G).

    python benchmarks/search_value.py --policy scalefree-general --scenario paper-64 \\
        --fit 1000000-1000049 --held 1000-1049

The slopes (knots at each band's mean steps left) go to ``VALUE_MAPS`` in ``policies/lookahead/search.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch
from wfbench.policies import get
from wfbench.policies.lookahead.critic import tap_values
from wfbench.policies.neural.policy import NetworkPolicy

import wfbench
from wfbench.core.simulator import Simulator

BANDS = ((0, 10), (10, 25), (25, 50), (50, 100), (100, 200), (200, 300), (300, 400), (400, 600), (600, 800))


def seeds(spec: str) -> list[int]:
    a, b = (int(x) for x in spec.split("-"))
    return list(range(a, b + 1))


def play(policy: str, scenario: str, seed_list: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """(V, G), each (T, B): the critic's value of each step's observation and the NSW summed from that step on."""
    base = get(policy)
    p = NetworkPolicy(base.model, mode="greedy", device="cpu", seed=base.seed, name="greedy", threads=1)
    values: list[np.ndarray] = []
    tap_values(p, values.append)
    sim = Simulator(wfbench.scenario(scenario), seed_list, keep_series=False)
    obs = sim.reset()
    p.reset(seed_list)
    rewards = []
    while not sim.done:
        rewards.append(np.asarray(sim.step(p.act(obs)), dtype=np.float64).copy())
        obs = sim.observe()
    r = np.stack(rewards)
    G = np.cumsum(r[::-1], 0)[::-1]
    return np.stack(values).astype(np.float64), G


def within(V: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return V - V.mean(1, keepdims=True), G - G.mean(1, keepdims=True)


def band_sums(V: np.ndarray, G: np.ndarray) -> dict[tuple[int, int], tuple[float, float, float]]:
    """Per band of steps left: the within-step sums (V G, V V) and the mean steps left, for a slope fit."""
    T = V.shape[0]
    left = T - np.arange(T)
    out = {}
    for lo, hi in BANDS:
        rows = (left > lo) & (left <= hi)
        rows[0] = False
        if rows.any():
            v, g = within(V[rows], G[rows])
            out[(lo, hi)] = (float((v * g).sum()), float((v * v).sum()), float(left[rows].mean()))
    return out


def knots_of(sums: list[dict]) -> tuple[tuple[int, float], ...]:
    """(steps left, slope) knots of the pooled band sums of one or several worlds."""
    out = []
    for band in BANDS:
        got = [s[band] for s in sums if band in s]
        if got:
            slope = sum(x[0] for x in got) / sum(x[1] for x in got)
            out.append((round(float(np.mean([x[2] for x in got]))), round(slope, 2)))
    return tuple(out)


def unseen_rows(policy: str, world: str, seed_list: list[int], others: tuple) -> str:
    """Two table rows: the 10 ms search on ``world`` with its own value map, and with ``others`` (fitted without it)."""
    from wfbench.policies.lookahead.search import NetworkSearch

    base = wfbench.evaluate(policy, world, seed_list)["nsw"].to_numpy()
    rows = []
    for label, value in (("its own", None), ("the others' pooled", others)):
        pol = NetworkSearch(get(policy), budget="10ms", value=value)
        nsw = wfbench.evaluate(pol, world, seed_list, act_timeout_s=None)["nsw"].to_numpy()
        d = nsw - base
        rows.append(f"| {world} | {label} | {nsw.mean():.4f} | {d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(d.size):.4f} "
                    f"| {pol.timing['deviations'] / len(seed_list):.1f} |")
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", default="scalefree-general")
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--fit", default="1000000-1000049", help="training seeds the slope is fitted on")
    ap.add_argument("--held", default="1000-1049", help="public seeds the error is measured on")
    ap.add_argument("--worlds", nargs="*", default=[], help="also fit a map per world and pooled over them")
    ap.add_argument("--leave-one-out", action="store_true",
                    help="with --worlds: each world's own slopes against the pooled slopes of the others")
    ap.add_argument("--search", default="", help="with --leave-one-out: public seeds a-b on which the 10 ms "
                    "search plays each world with its own map and with the others' pooled one")
    a = ap.parse_args()
    torch.set_num_threads(1)
    print(f"machine: {platform.node()} {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; "
          f"{a.policy} greedy on {a.scenario}")
    t0 = time.process_time()
    Vf, Gf = play(a.policy, a.scenario, seeds(a.fit))
    Vh, Gh = play(a.policy, a.scenario, seeds(a.held))
    T = Vf.shape[0]
    left = T - np.arange(T)  # steps left at each step's observation
    knots, slopes = [], []
    print(f"fit on {a.fit}, error on {a.held}: G_s (NSW summed from step s to the end) ~ a_s + b(L) * V_s, "
          f"L the steps left, b fitted within a step per band of L")
    print("| steps left L | b(L) | G mean | RMSE, step only | RMSE, step + b(L) V | R^2 within a step | "
          "corr(V, G) within a step |")
    print("|---|---|---|---|---|---|---|")
    for lo, hi in BANDS:
        rows = (left > lo) & (left <= hi)
        rows[0] = False
        if not rows.any():  # a world shorter than the band (small: 200 steps), as band_sums skips it
            continue
        vf, gf = within(Vf[rows], Gf[rows])
        b = float((vf * gf).sum() / (vf * vf).sum())
        knots.append(float(left[rows].mean()))
        slopes.append(b)
        a_s = Gf[rows].mean(1) - b * Vf[rows].mean(1)  # the step's intercept, from the fit seeds
        V, G = Vh[rows], Gh[rows]
        base = G - Gf[rows].mean(1)[:, None]
        err = G - (a_s[:, None] + b * V)
        v, g = within(V, G)
        r2 = 1 - ((g - b * v) ** 2).sum() / (g * g).sum()
        corr = float((v * g).sum() / np.sqrt((v * v).sum() * (g * g).sum()))
        print(f"| {lo + 1}-{hi} | {b:.2f} | {G.mean():.1f} | {np.sqrt((base ** 2).mean()):.2f} | "
              f"{np.sqrt((err ** 2).mean()):.2f} | {r2:.3f} | {corr:.3f} |")
    print("VALUE_MAPS entry (steps left, slope) knots, interpolated linearly:")
    print("    " + repr(tuple((round(k), round(b, 2)) for k, b in zip(knots, slopes, strict=True))))
    sums = []
    for world in a.worlds:
        sums.append(band_sums(*play(a.policy, world, seeds(a.fit))))
        print(f"{world}: {knots_of(sums[-1:])}", flush=True)
    if sums:
        print(f"pooled over {', '.join(a.worlds)}: {knots_of(sums)}")
    if a.leave_one_out and len(sums) > 1:  # what the pooled map is for a world it was not fitted on
        print("| world | its own slope / the pooled slope of the others, per band of steps left |")
        print("|---|---|")
        for i, world in enumerate(a.worlds):
            own, others = knots_of(sums[i:i + 1]), knots_of(sums[:i] + sums[i + 1:])
            ratios = ", ".join(f"{k}: {b / o:.2f}" for (k, b), (_, o) in zip(own, others, strict=False))
            print(f"| {world} | {ratios} |")
        if a.search:  # and what it costs a search there: its own map against the others' pooled one
            print(f"the 10 ms search on public seeds {a.search}, paired by seed against {a.policy}:")
            print("| world | value map | NSW mean | paired difference (± s.e.) | deviations an episode |")
            print("|---|---|---|---|---|")
            for i, world in enumerate(a.worlds):
                others = knots_of(sums[:i] + sums[i + 1:])
                print(unseen_rows(a.policy, world, seeds(a.search), others), flush=True)
    print(f"CPU {time.process_time() - t0:.1f} s")


if __name__ == "__main__":
    main()
