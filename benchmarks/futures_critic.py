"""Collect, fit and measure the search's futures critic (issue #52, ``policies/lookahead/critic.py``).

The search ends each future at a value; PPO's critic, mapped into summed NSW, misjudges one more
person on worlds it was not trained on (docs/policies.md). This fits a critic for the job on the
training split only:

- **collect**: on each training world and training seeds (1,000,000 and up), the network plays
  its sampled mode up to a step ``t0`` and its greedy mode after it (a search's futures are
  reached by the sampled network and played greedily), ``t0`` spread over the episode; every
  ``--stride`` steps from ``t0`` on it keeps the network's summary (its value head's input), the
  steps left L and the mean NSW per step of the rest of that episode;
- **fit**: an MLP of (summary, L) to that mean, weighted by L^2 (the search adds L times it, so
  an error counts as L times it does), on the collected rows; the public seeds are never fitted;
- **pairs**: the observational rows above fit a critic that ranks *states* well and *actions*
  badly (a state's summary carries what its episode's demand did; a hire is judged by what
  hiring states' futures did). So, at the search's own deliberations (the network playing its
  sampled mode at the root, as the search does, and never deviating), the network's top
  candidates are each played on K futures sampled from the belief with common random numbers,
  greedily **to the end**; each future keeps the summary at the search's cut (H steps) and the
  NSW summed after it. A group is one (decision, future k); within it the candidates differ by
  their action only, so fitting ``L x critic`` to the NSW after the cut within groups (group
  fixed effects) fits what the search uses: the difference an action makes;
- **fit --pairs**: that fit, from the observational critic's weights;
- **measure**: on public seeds 1000-1049 of each training world, greedy episodes, the error of
  L x critic against the NSW summed to the end, within a step (candidates are compared at the
  same step, so only the within-step part matters), beside the calibrated PPO critic's.

    NUMBA_NUM_THREADS=1 python benchmarks/futures_critic.py collect --out runs/futures-critic
    NUMBA_NUM_THREADS=1 python benchmarks/futures_critic.py fit --out runs/futures-critic
    NUMBA_NUM_THREADS=1 python benchmarks/futures_critic.py pairs --out runs/futures-critic
    NUMBA_NUM_THREADS=1 python benchmarks/futures_critic.py fit --out runs/futures-critic --pairs
    NUMBA_NUM_THREADS=1 python benchmarks/futures_critic.py measure --out runs/futures-critic --held 1000-1019

The search with it: ``benchmarks/search_budget.py --knobs 8:20:20:3:1:critic=runs/futures-critic/critic.pt``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch
from wfbench.policies import get
from wfbench.policies.lookahead.critic import FuturesCritic, Summary, left_features, tap_values
from wfbench.policies.lookahead.network_rollout import PURPOSE_NOISE
from wfbench.policies.lookahead.search import NetworkSearch, candidates, value_map, value_slope
from wfbench.policies.neural.policy import NetworkPolicy

import wfbench
from wfbench.core.simulator import Simulator
from wfbench.scenarios.suites import get_suite

TRAIN_SEED = 1_000_000


def train_worlds() -> list[str]:
    return [s.preset for s in get_suite("suite-v1").scenarios if s.split == "train"]


def play(policy: str, world: str, seed_list: list[int], t0: int, stride: int) -> dict[str, np.ndarray]:
    """One batch: sampled play before ``t0``, greedy from it; the rows kept every ``stride`` steps from ``t0``."""
    base = get(policy)
    p = NetworkPolicy(base.model, mode="sample" if t0 > 0 else "greedy", device="cpu", seed=base.seed,
                      name="collect", threads=1)
    summary = Summary(base.model)
    values: list[np.ndarray] = []
    tap_values(p, values.append)
    try:
        sim = Simulator(wfbench.scenario(world), seed_list, keep_series=False)
        obs = sim.reset()
        p.reset(seed_list)
        tops, steps, rewards = [], [], []
        t = 0
        while not sim.done:
            if t == t0:
                p.mode = "greedy"
            action = p.act(obs)
            if t >= t0 and (t - t0) % stride == 0:
                tops.append(summary.last.numpy().copy())
                steps.append(t)
            rewards.append(np.asarray(sim.step(action), dtype=np.float64).copy())
            obs = sim.observe()
            t += 1
    finally:
        summary.close()
    r = np.stack(rewards)  # (T, B)
    T = r.shape[0]
    G = np.cumsum(r[::-1], 0)[::-1]
    at = np.asarray(steps)
    left = T - at
    V = np.stack(values)[at]
    return {"top": np.stack(tops).astype(np.float32), "left": np.repeat(left[:, None], r.shape[1], 1),
            "G": G[at], "V": V, "horizon": np.int64(T)}


def collect(a: argparse.Namespace) -> None:
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    shares = [float(x) for x in a.t0.split(",")]
    for w_i, world in enumerate(a.worlds or train_worlds()):
        t0s = [int(round(f * wfbench.scenario(world).horizon)) for f in shares]
        path = out / f"collect-{world}.npz"
        if path.exists():
            print(f"{world}: kept {path}")
            continue
        start = time.process_time()
        parts = []
        for j, t0 in enumerate(t0s):
            first = TRAIN_SEED + 10_000 * w_i + a.envs * j
            parts.append(play(a.policy, world, list(range(first, first + a.envs)), t0, a.stride))
        np.savez_compressed(path, **{k: np.concatenate([p[k].reshape(-1, *p[k].shape[2:]) for p in parts])
                                     for k in ("top", "left", "G", "V")},
                            horizon=parts[0]["horizon"])
        print(f"{world}: {sum(p['top'].shape[0] * p['top'].shape[1] for p in parts)} rows, "
              f"{time.process_time() - start:.0f} CPU s", flush=True)


class PairCollector(NetworkSearch):
    """The search's deliberations, each candidate played greedily to the end on K futures; it never deviates."""

    def __init__(self, base, share: float, **knobs):
        super().__init__(base, **knobs)
        self.share = share
        self.rows: dict[str, list] = {k: [] for k in ("top", "left", "G", "first", "group", "cand", "V")}
        self.last_value = None
        self.groups = 0

    def _start(self, obs):
        super()._start(obs)
        self.summary = Summary(self.base.model)
        # PPO's critic at the cut, for its map's paired error beside the fitted critic's
        tap_values(self.player, lambda v: setattr(self, "last_value", v))

    def _search(self, obs, envs, action, t):
        left = self.horizon - t - self.H  # steps left at the cut
        if left <= 0:
            return
        keep = np.random.default_rng([int(self._seeds[0]), t, 0x5041]).random(len(envs)) < self.share
        envs = envs[keep]
        if not len(envs):
            return
        with torch.no_grad():
            out, x = self._heads_before(obs)
        logits = out["workforce"].float().numpy()
        w = action["workforce"]
        cands = candidates(w[envs], logits[envs], np.asarray(obs["workforce_mask"])[envs], self.top)
        pos = self._positions(out, x, envs)
        M = action["positioning"].shape[-1]
        # the rows as NetworkSearch._search lays them out (its file decides the campaign's search pieces, so it is not
        # split into a shared helper while the held-out reference is played; docs/hindsight.md, "The queue")
        rows_env, rows_a, rows_k, first_p, group, cand = [], [], [], [], [], []
        for i, (b, cs) in enumerate(zip(envs, cands, strict=True)):
            for j, a in enumerate(cs):
                p_row = action["positioning"][b] if j == 0 else np.zeros((2, M))
                if j:
                    p_row[int(a >= 4), pos[i, int(a >= 4)]] = 1.0
                for k in range(self.K):
                    rows_env.append(int(b))
                    rows_a.append(a)
                    rows_k.append(k)
                    first_p.append(p_row)
                    group.append(self.groups + i * self.K + k)
                    cand.append(j)
        self.groups += len(envs) * self.K
        env_idx = np.asarray(rows_env, dtype=np.int64)
        first = {"dispatch": action["dispatch"][env_idx], "workforce": np.asarray(rows_a, dtype=np.int64),
                 "positioning": np.stack(first_p)}
        n = len(rows_env)
        fork = self._fork(n)
        rest = self.horizon - t
        self.belief.sample_into(fork, env_idx, np.asarray(rows_k, dtype=np.int64), rest)
        p = self.player
        h, c = self.base._state
        idx = torch.as_tensor(env_idx)
        p._state = (h[:, idx].clone(), c[:, idx].clone())
        p._starts = torch.zeros(1, n)
        if self.futures == "sample":  # the network's own noise in the futures, world k's the same for every candidate
            p._rngs = [np.random.default_rng([int(self._seeds[e]), self.seed, PURPOSE_NOISE, t, k])
                       for e, k in zip(rows_env, rows_k, strict=True)]
        head_total, fobs = fork.step_observe(first)
        after = np.zeros(n)
        top = V = None
        for step in range(1, rest):
            act = p.act(fobs)
            if step == self.H:  # the search's cut: its summary, and what follows it
                top, V = self.summary.last.numpy().copy(), self.last_value
            r, fobs = fork.step_observe(act)
            if step < self.H:
                head_total = head_total + r
            else:
                after = after + r
        self.rows["top"].append(top.astype(np.float32))
        self.rows["left"].append(np.full(n, left))
        self.rows["G"].append(after)
        self.rows["first"].append(np.asarray(head_total, dtype=np.float64))
        self.rows["group"].append(np.asarray(group))
        self.rows["cand"].append(np.asarray(cand))
        self.rows["V"].append(V)
        self.timing["decisions"] += len(envs)


def pairs(a: argparse.Namespace) -> None:
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    for w_i, world in enumerate(a.worlds or train_worlds()):
        path = out / f"pairs-{world}.npz"
        if path.exists():
            print(f"{world}: kept {path}")
            continue
        start = time.process_time()
        first = TRAIN_SEED + 500_000 + 10_000 * w_i
        col = PairCollector(get(a.policy), a.share, K=a.K, H=20, R=20, top=3, z=1.0, futures=a.futures)
        wfbench.evaluate(col, world, list(range(first, first + a.envs)), act_timeout_s=None)
        col.summary.close()
        rows = {k: np.concatenate(v) for k, v in col.rows.items() if v}
        horizon = wfbench.scenario(world).horizon
        np.savez_compressed(path, horizon=np.int64(horizon), **rows)
        print(f"{world}: {col.groups} groups, {len(rows['G'])} futures, {time.process_time() - start:.0f} CPU s",
              flush=True)


def fit(a: argparse.Namespace) -> None:
    out = Path(a.out)
    data = [np.load(p) for p in sorted(out.glob("collect-*.npz"))]
    top = torch.from_numpy(np.concatenate([d["top"] for d in data]))
    left = torch.from_numpy(np.concatenate([d["left"] for d in data]).astype(np.float32))
    G = torch.from_numpy(np.concatenate([d["G"] for d in data]).astype(np.float32))
    horizon = np.concatenate([np.full(d["left"].shape, int(d["horizon"])) for d in data])
    horizon_t = torch.from_numpy(horizon.astype(np.float32))
    y = G / left
    torch.manual_seed(a.seed)
    critic = FuturesCritic(top.shape[1], a.width, seed=a.seed)
    critic.mean = float(y.mean())
    w = (left / left.mean()) ** 2
    opt = torch.optim.Adam(critic.net.parameters(), lr=a.lr)
    n = len(y)
    start = time.process_time()
    x_left = left_features(left, horizon_t)
    for epoch in range(a.epochs):
        perm = torch.randperm(n)
        total = 0.0
        for i in range(0, n, a.batch):
            b = perm[i:i + a.batch]
            pred = critic.net(torch.cat([top[b], x_left[b]], -1)).squeeze(-1) + critic.mean
            loss = (w[b] * (pred - y[b]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss) * len(b)
        print(f"epoch {epoch + 1}: weighted MSE {total / n:.3e}", flush=True)
    critic.net.eval()
    critic.save(out / "critic.pt")
    (out / "fit.json").write_text(json.dumps({"rows": n, "worlds": [str(p.name) for p in sorted(out.glob(
        "collect-*.npz"))], "epochs": a.epochs, "lr": a.lr, "width": a.width, "seed": a.seed,
        "cpu_s": time.process_time() - start}, indent=1))
    print(f"{out / 'critic.pt'}: {n} rows, {time.process_time() - start:.0f} CPU s")


def _pair_data(out: Path, policy: str) -> dict[str, torch.Tensor]:
    """Every world's pairs, groups numbered apart, as tensors; with PPO's critic through its own and the pooled map."""
    parts, offset = [], 0
    for path in sorted(out.glob("pairs-*.npz")):
        d = dict(np.load(path))
        world = path.stem.removeprefix("pairs-")
        for key, knots in (("ppo", value_map(policy, world)), ("ppo_pooled", value_map(policy, "*"))):
            d[key] = np.vectorize(lambda L, knots=knots: value_slope(knots, int(L)))(d["left"]) * d["V"]
        d["group"] = d["group"] + offset
        offset = int(d["group"].max()) + 1
        d["horizon"] = np.full(d["G"].shape, int(d["horizon"]))
        parts.append(d)
    return {k: torch.from_numpy(np.concatenate([d[k] for d in parts]).astype(np.int64 if k == "group" else
                                                                           np.float32)) for k in parts[0]}


def _within(x: torch.Tensor, group: torch.Tensor, n_groups: int) -> torch.Tensor:
    """x minus its group's mean."""
    total = torch.zeros(n_groups).index_add(0, group, x)
    count = torch.zeros(n_groups).index_add(0, group, torch.ones_like(x))
    return x - (total / count)[group]


def fit_pairs(a: argparse.Namespace) -> None:
    """L x critic fitted to the NSW after the cut within groups (the candidates of one decision and future)."""
    out = Path(a.out)
    d = _pair_data(out, a.policy)
    critic = FuturesCritic.load(out / "critic.pt")
    groups = int(d["group"].max()) + 1
    gen = torch.Generator().manual_seed(a.seed)
    held = torch.rand(groups, generator=gen) < 0.2  # a fifth of the groups to choose the step on
    rows_fit, rows_held = ~held[d["group"]], held[d["group"]]
    g = _within(d["G"], d["group"], groups)
    first = _within(d["first"], d["group"], groups)
    x = torch.cat([d["top"], left_features(d["left"], d["horizon"])], -1)

    def residual():
        pred = d["left"] * (critic.net(x).squeeze(-1) + critic.mean)
        return g - _within(pred, d["group"], groups)

    def r2(res, rows):
        return float(1 - (res[rows] ** 2).sum() / (g[rows] ** 2).sum())

    with torch.no_grad():
        before = residual()
    print(f"{len(g)} futures in {groups} groups; within a group, the NSW after the cut: s.d. {float(g.std()):.3f}, "
          f"of the H steps: {float(first.std()):.3f}; the observational critic's R^2 within groups: "
          f"fit {r2(before, rows_fit):.3f}, held {r2(before, rows_held):.3f}; PPO's critic x its own map "
          f"{r2(g - _within(d['ppo'], d['group'], groups), rows_held):.3f}, x the pooled map "
          f"{r2(g - _within(d['ppo_pooled'], d['group'], groups), rows_held):.3f} (held)")
    opt = torch.optim.Adam(critic.net.parameters(), lr=a.lr)
    best, best_state, start = -np.inf, None, time.process_time()
    for step in range(a.steps):
        res = residual()
        loss = (res[rows_fit] ** 2).mean() / (g[rows_fit] ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        with torch.no_grad():
            score = r2(residual(), rows_held)
        if score > best:
            best, best_state = score, {k: v.clone() for k, v in critic.net.state_dict().items()}
        if (step + 1) % 50 == 0:
            print(f"step {step + 1}: R^2 within groups, fit {1 - loss.item():.3f}, held {score:.3f}", flush=True)
    critic.net.load_state_dict(best_state)
    critic.net.eval()
    critic.save(out / "critic-pairs.pt")
    print(f"{out / 'critic-pairs.pt'}: held R^2 within groups {best:.3f}, {time.process_time() - start:.0f} CPU s")


def measure(a: argparse.Namespace) -> None:
    """Within-step error of L x critic and of the calibrated PPO critic against G, greedy play, public seeds."""
    critic = FuturesCritic.load(Path(a.out) / "critic.pt")
    a_, b_ = (int(x) for x in a.held.split("-"))
    held = list(range(a_, b_ + 1))
    print("| world | R^2 within a step: PPO critic x its own map | x the pooled map | futures critic | "
          "RMSE within a step: step mean alone | PPO x own map | futures critic |")
    print("|---|---|---|---|---|---|---|")
    for world in a.worlds or train_worlds():
        d = play(a.policy, world, held, 0, a.stride)
        T = int(d["horizon"])
        left = d["left"].astype(np.float64)
        G = d["G"]
        rows = left[:, 0] > 1

        def within(x, rows=rows):
            return x[rows] - x[rows].mean(1, keepdims=True)

        def mapped(knots, left=left, V=d["V"]):
            return np.vectorize(lambda L: value_slope(knots, int(L)))(left) * V

        with torch.no_grad():
            fut = (torch.from_numpy(left.astype(np.float32)).reshape(-1)
                   * critic.per_step(torch.from_numpy(d["top"].reshape(-1, d["top"].shape[-1])),
                                     left.reshape(-1), T)).numpy().reshape(left.shape)
        g = within(G)
        r2, rmse = [], []
        for pred in (mapped(value_map(a.policy, world)), mapped(value_map(a.policy, "*")), fut):
            e = g - within(pred)  # within a step: a step's intercept cancels between candidates
            r2.append(1 - (e ** 2).sum() / (g * g).sum())
            rmse.append(np.sqrt((e ** 2).mean()))
        print(f"| {world} | {r2[0]:.3f} | {r2[1]:.3f} | {r2[2]:.3f} | {np.sqrt((g * g).mean()):.2f} | {rmse[0]:.2f} | "
              f"{rmse[2]:.2f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("collect", "pairs", "fit", "measure"):
        s = sub.add_parser(name)
        s.add_argument("--out", required=True, help="the folder of the collected rows and the critic")
        s.add_argument("--policy", default="scalefree-general")
        s.add_argument("--worlds", nargs="*", default=[], help="default: the training split of suite-v1")
        s.add_argument("--stride", type=int, default=4, help="keep every stride-th step")
    sub.choices["collect"].add_argument("--envs", type=int, default=16, help="environments per batch")
    sub.choices["collect"].add_argument("--t0", default="0,0.125,0.25,0.375,0.5,0.625,0.75,0.875",
                                        help="where the sampled play turns greedy, as shares of the horizon, one "
                                        "batch each")
    sub.choices["pairs"].add_argument("--envs", type=int, default=16, help="environments (training seeds) a world")
    sub.choices["pairs"].add_argument("--K", type=int, default=4, help="futures per candidate")
    sub.choices["pairs"].add_argument("--futures", default="greedy", choices=("greedy", "sample"),
                                      help="how the network plays the futures after the candidates")
    sub.choices["pairs"].add_argument("--share", type=float, default=0.3,
                                      help="the share of the search's deliberations played to the end")
    sub.choices["fit"].add_argument("--pairs", action="store_true",
                                    help="fit the critic's paired differences (from critic.pt) -> critic-pairs.pt")
    sub.choices["fit"].add_argument("--steps", type=int, default=400, help="with --pairs: full-batch Adam steps")
    sub.choices["fit"].add_argument("--epochs", type=int, default=20)
    sub.choices["fit"].add_argument("--lr", type=float, default=1e-3)
    sub.choices["fit"].add_argument("--batch", type=int, default=1024)
    sub.choices["fit"].add_argument("--width", type=int, default=64)
    sub.choices["fit"].add_argument("--seed", type=int, default=0)
    sub.choices["measure"].add_argument("--held", default="1000-1019", help="public seeds a-b")
    a = ap.parse_args()
    torch.set_num_threads(1)
    print(f"machine: {platform.node()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    {"collect": collect, "pairs": pairs, "fit": fit_pairs if getattr(a, "pairs", False) else fit,
     "measure": measure}[a.cmd](a)


if __name__ == "__main__":
    main()
