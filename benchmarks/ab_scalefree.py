"""What each choice of the scale-free network costs or saves (issue #32), measured one at a time.

On a batch of real observations (``--scenario``, B environments played ``--steps`` steps by
the heuristic, one torch thread), forward plus backward of the piece each choice replaces,
the alternative beside it, same widths (d = 32, memory 32):

- ``pointer``: the dispatch pointer over every facility and every person, (B, M, N + 1)
  logits with the distance prior (the networks before), against the scale-free pointer on
  the facilities that choose, over their k candidates, with the pair features, the
  context-conditioned prior and the clipping;
- ``positioning``: the positioning head on every environment, against only those whose
  workforce action hires or lets go (the share is ``--hire-share``, the untrained
  network's 6% by default);
- ``memory``: the memory concatenated to every facility and person row and projected
  (the networks before), against the memory entering once per environment (into the
  heads and the pointer's queries).

Prints milliseconds per call (median of ``--repeat``) and per 1,000 env-steps. Usage::

    python benchmarks/ab_scalefree.py --scenario paper-64 --envs 128 --repeat 20
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from wfbench.policies.neural import scalefree

from wfbench import policies
from wfbench.core.observation_v2 import observe_v2
from wfbench.core.simulator import Simulator
from wfbench.harness.budget import machine, machine_line
from wfbench.scenarios.resolve import resolve_scenario


def batch(scenario: str, B: int, steps: int) -> dict:
    sim = Simulator(resolve_scenario(scenario), list(range(1000, 1000 + B)), keep_series=False, threads=1)
    obs = sim.reset()
    pol = policies.get("heuristic")
    pol.reset(list(range(1000, 1000 + B)))
    for _ in range(steps):
        obs = sim.step_observe(pol.act(obs))[1]
    return scalefree.featurize(scalefree.obs_to_torch(observe_v2(obs)), 8, 3)


def timed(fn, repeat: int) -> float:
    fn()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return float(np.median(out)) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="paper-64")
    ap.add_argument("--envs", type=int, default=128)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--hire-share", type=float, default=0.06)
    a = ap.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    x = batch(a.scenario, a.envs, a.steps)
    net = scalefree.ScaleFreeNet(scalefree.scalefree_config())
    R, M = x["choose"].shape
    N = x["per_in"].shape[1]
    d = net.config.d
    fac = torch.randn(R, M, d, requires_grad=True)
    per = torch.randn(R, N, d, requires_grad=True)
    mem = torch.randn(R, net.config.lstm, requires_grad=True)
    g = torch.randn(R, d, requires_grad=True)
    dist = torch.rand(R, M, N) * 64
    rows, facs = x["choose"].nonzero(as_tuple=True)
    ptr_q, ptr_k, noop = nn.Linear(d, d), nn.Linear(d, d), nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, 1))
    scale = nn.Parameter(torch.tensor(3.0))

    def dense_pointer():
        q, k = ptr_q(fac), ptr_k(per)
        logits = q @ k.transpose(-1, -2) / d ** 0.5 - (F.softplus(scale) * 8.0) * dist
        torch.cat([logits, noop(fac)], -1).sum().backward()

    def sparse_pointer():
        cand, tt = x["cand"][rows, facs], x["tt"][rows, facs]
        q = net.ptr_q(fac[rows, facs]) + net.ptr_mem(mem[rows])
        keys = net.ptr_k(per[rows[:, None], cand.clamp_max(N - 1)])
        kk = tt.shape[1]
        rank = torch.arange(kk, dtype=tt.dtype).expand_as(tt) / kk
        pair = net.pair(torch.stack([torch.log1p(tt), rank, (tt - tt[:, :1]) / (1 + tt[:, :1])], -1)).squeeze(-1)
        alpha = F.softplus(net.alpha(torch.cat([g[rows], mem[rows]], -1)))
        logits = (keys @ q[:, :, None]).squeeze(-1) / d ** 0.5 + pair - alpha * tt
        (scalefree.CLIP * torch.tanh(torch.cat([logits, net.noop(q)], -1) / scalefree.CLIP)).sum().backward()

    used = torch.randperm(R)[: max(1, int(round(a.hire_share * R)))]
    which = torch.zeros(len(used), dtype=torch.long)
    out = {"fac": fac, "mem": mem}

    def positioning_all():
        net.pos_head(fac + net.pos_mem(mem)[:, None]).sum().backward()

    def positioning_used():
        net.positioning(out, used, which).sum().backward()

    fuse_f, fuse_p = nn.Linear(d + net.config.lstm, d), nn.Linear(d + net.config.lstm, d)

    def memory_per_entity():
        f = fuse_f(torch.cat([fac, mem[:, None].expand(-1, M, -1)], -1))
        p = fuse_p(torch.cat([per, mem[:, None].expand(-1, N, -1)], -1))
        (f.sum() + p.sum()).backward()

    def memory_once():
        (net.ptr_mem(mem).sum() + net.pos_mem(mem).sum()).backward()

    print(f"{a.scenario}: {R} env-steps, {M} x {N} slots, {len(rows)} choosing facilities "
          f"({len(rows) / R:.2f} per env-step), k = {net.config.k}; forward + backward, one thread")
    for name, before, after in (("pointer", dense_pointer, sparse_pointer),
                                ("positioning", positioning_all, positioning_used),
                                ("memory", memory_per_entity, memory_once)):
        tb, ta = timed(before, a.repeat), timed(after, a.repeat)
        print(f"  {name:12s} before {tb:8.2f} ms ({tb / R * 1e3:7.2f} per 1k env-steps)   "
              f"scale-free {ta:8.2f} ms ({ta / R * 1e3:7.2f} per 1k env-steps)   saves {tb - ta:8.2f} ms")
    print(machine_line(machine()))


if __name__ == "__main__":
    main()
