"""Score and CPU cost of search with the network against its base, per preset or knob setting (issue #52).

Each entry plays the same public seeds in one batch in this process, as ``wfbench evaluate
--backend serial`` does; its cost is the frontier's (CPU seconds of whole episodes over their
env-steps: observing, simulating and the policy). The paired difference to the base is per seed.

    NUMBA_NUM_THREADS=1 python benchmarks/search_budget.py --scenario paper-64 --seeds 1000-1009 \\
        --policies scalefree-general scalefree-general@greedy search-scalefree-general-1ms \\
        search-scalefree-general search-scalefree-general-100ms --knobs 8:20:20:3:1

``--knobs K:H:R:top:z`` adds a :class:`NetworkSearch` of the base with those knobs; flags after
them ablate one ingredient each: ``:novalue`` (the H steps alone, the critic left out),
``:sample`` (the network samples the futures instead of playing them greedily), ``:period``
(it deliberates every R steps only, not also where the network hires or lets go); ``:propose=NAME``
adds a second proposer (``NetworkSearch(propose=get(NAME))``: its workforce action joins the
candidates), ``:asks`` with it deliberates where the proposer hires or lets go too;
``:critic=PATH`` ends the futures at a futures critic instead of PPO's (``CriticSearch``,
``benchmarks/futures_critic.py``); ``:tail=NAME`` completes each future by the compiled composite
NAME's play to the episode's end instead (``TailSearch``). The noise
test's ablation is a tiny z (``z=1e-9``: any positive mean wins).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch
from wfbench.policies import get
from wfbench.policies.lookahead.critic import CriticSearch
from wfbench.policies.lookahead.search import NetworkSearch
from wfbench.policies.lookahead.tail import TailSearch

import wfbench


def seeds(spec: str) -> list[int]:
    a, b = (int(x) for x in spec.split("-"))
    return list(range(a, b + 1))


def entry(spec: str, base: str) -> tuple[str, object]:
    if ":" not in spec:
        return spec, get(spec)
    parts = spec.split(":")
    K, H, R, top = (int(x) for x in parts[:4])
    flags = set(parts[5:])
    proposers = {f for f in flags if f.startswith("propose=")}
    critics = {f for f in flags if f.startswith("critic=")}
    tails = {f for f in flags if f.startswith("tail=")}
    known = {"novalue", "sample", "period", "asks"} | proposers | critics | tails
    if flags - known or len(proposers) > 1 or ("asks" in flags and not proposers) or len(critics | tails) > 1 or (
            (critics or tails) and "novalue" in flags):
        raise SystemExit(f"--knobs {spec}: unknown flags {sorted(flags - known)}; allowed: novalue, sample, period, "
                         "one propose=POLICY, and asks with it, one critic=PATH or tail=COMPOSITE (not with novalue)")
    kw = {"value": ()} if "novalue" in flags else {}
    if "period" in flags:
        kw["decide"] = "period"
    if "sample" in flags:
        kw["futures"] = "sample"
    if proposers:
        kw["propose"] = get(proposers.pop().split("=", 1)[1])
        kw["propose_asks"] = "asks" in flags
    label = "".join(f" {f}" for f in sorted(flags))
    name = f"search K={K} H={H} R={R} top={top} z={parts[4]}{label}"
    knobs = {"K": K, "H": H, "R": R, "top": top, "z": float(parts[4])}
    if critics:
        return name, CriticSearch(get(base), critics.pop().split("=", 1)[1], **knobs, **kw)
    if tails:
        return name, TailSearch(get(base), get(tails.pop().split("=", 1)[1]), **knobs, **kw)
    return name, NetworkSearch(get(base), **knobs, **kw)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--seeds", default="1000-1009", help="public seeds a-b (never the test seeds 0-49)")
    ap.add_argument("--base", default="scalefree-general")
    ap.add_argument("--policies", nargs="*", default=[])
    ap.add_argument("--knobs", nargs="*", default=[], help="K:H:R:top:z[:novalue] settings of a NetworkSearch")
    a = ap.parse_args()
    torch.set_num_threads(1)
    s = seeds(a.seeds)
    print(f"machine: {platform.node()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; {a.scenario} seeds "
          f"{a.seeds}; numba threads {os.environ.get('NUMBA_NUM_THREADS', 'default')}")
    print("| policy | NSW mean | paired diff to base (± s.e.) | CPU ms per env-step | hires | let-goes | "
          "deviations per episode | wall s |")
    print("|---|---|---|---|---|---|---|---|")
    base_nsw = wfbench.evaluate(a.base, a.scenario, s)["nsw"].to_numpy()
    for spec in [*a.policies, *a.knobs]:
        name, policy = entry(spec, a.base)
        t0 = time.perf_counter()
        df = wfbench.evaluate(policy, a.scenario, s, act_timeout_s=None)
        wall = time.perf_counter() - t0
        d = df["nsw"].to_numpy() - base_nsw
        ms = 1e3 * df["cpu_s"].sum() / df["episode_length"].sum()
        dev = getattr(policy, "timing", {}).get("deviations", float("nan")) / len(s)
        took = getattr(policy, "timing", {}).get("proposed", 0.0) / len(s)
        if getattr(policy, "propose", None) is not None:
            name = f"{name} (the proposer's taken {took:.1f} an episode)"
        print(f"| {name} | {df['nsw'].mean():.4f} | {d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f} | "
              f"{ms:.2f} | {df['hires'].mean():.1f} | {df['releases'].mean():.1f} | {dev:.1f} | {wall:.0f} |",
              flush=True)


if __name__ == "__main__":
    main()
