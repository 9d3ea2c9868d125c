"""Search with the network: a truncated rollout that deviates from its network only beyond the noise (issue #52).

:class:`NetworkSearch` is :class:`~wfbench.policies.lookahead.network_rollout.NetworkRollout` with
the three cures of its winner's curse (``/work/shared/notes/learned-search.md``):

- **greedy futures**: a copy of the network plays every sampled world in its greedy mode, so
  world k is the same deterministic future for every candidate (common random numbers without
  any policy noise);
- **truncation at the network's value**: each future ends after ``H`` steps at the critic's
  estimate of what is left, mapped into summed NSW by the slope :data:`VALUE_MAPS` fitted for
  the base (``benchmarks/search_value.py``; a base without one is scored on its ``H`` steps
  alone);
- **a noise test**: the candidates are the network's own workforce action and its next most
  probable ones (``top`` in all, masked), and it plays another than its own only when that
  candidate's paired advantage over the K worlds exceeds ``z`` standard errors.

Everything else (dispatch, the positioning of the network's own action, when to decide) is
the network's and :class:`NetworkRollout`'s. ``docs/policies.md``, "search-scalefree-general".
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
from wfbench.policies.lookahead.knobs import positive, whole
from wfbench.policies.lookahead.network_rollout import PURPOSE_NOISE, NetworkRollout
from wfbench.policies.lookahead.rollout import DEFAULT_BUDGET

from wfbench.core.config import ScenarioConfig

# budget presets: (K, H, R, top, z), named by the CPU time per env-step they aim at on paper-64 (one core,
# whole episodes); chosen on public seeds 1000-1009 (docs/policies.md, "search-scalefree-general")
BUDGETS: dict[str, tuple[int, int, int, int, float]] = {
    "1ms": (2, 10, 80, 2, 1.0),
    "10ms": (8, 20, 20, 3, 1.0),
    "100ms": (32, 20, 10, 4, 1.0),
}
KNOBS = {"K": ("sampled futures per candidate", "an integer >= 2"),
         "H": ("steps of each future before the value ends it", "an integer >= 1"),
         "R": ("steps between two decisions the network did not ask for", "an integer >= 1"),
         "top": ("candidates: the network's own workforce action and its next most probable", "an integer >= 1"),
         "z": ("standard errors a candidate's paired advantage must exceed", "a number > 0")}

# the critic's value -> NSW summed over the rest of the episode: per base and world, (steps left, slope) knots, the
# slope interpolated linearly in the steps left (the critic is discounted and does not see the end, and its units
# are each training world's normalized return). Fitted within a step (step fixed effects) under the network's greedy
# play on training seeds 1000000-1000049 of each of its training worlds, "*" pooled over them for any other world
# (the held-out ones are never fitted), by `python benchmarks/search_value.py --worlds ...`, which prints the error
# on public seeds 1000-1049 (docs/policies.md, "search-scalefree-general"). A step's intercept is left out: every
# candidate's future ends at the same step
VALUE_MAPS: dict[str, dict[str, tuple[tuple[int, float], ...]]] = {
    "scalefree-general": {
        "small": ((6, 3.01), (18, 6.39), (38, 7.31), (76, 7.22), (150, 6.56)),
        "paper-64": ((6, 2.83), (18, 8.53), (38, 13.35), (76, 21.13), (150, 29.59), (250, 35.45), (350, 47.63),
                     (500, 54.78), (700, 37.53)),
        "nonstationary": ((6, 2.69), (18, 8.58), (38, 15.31), (76, 25.61), (150, 32.44), (250, 40.23), (350, 50.93),
                          (500, 43.36), (700, 13.0)),
        "table2-g32-f25-s10": ((6, 3.4), (18, 8.63), (38, 12.75), (76, 19.02), (150, 28.99), (250, 42.39),
                               (350, 53.12), (500, 78.47), (700, 69.8)),
        "table2-g256-f25-s5": ((6, 4.72), (18, 12.94), (38, 23.12), (76, 39.82), (150, 61.74), (250, 65.61),
                               (350, 62.99), (500, 56.24), (700, 41.72)),
        "surge-64": ((6, 3.24), (18, 8.66), (38, 15.72), (76, 20.72), (150, 31.49), (250, 27.63), (350, 1.8),
                     (500, 13.4), (700, 24.64)),
        "clustered-64": ((6, 2.43), (18, 5.81), (38, 10.29), (76, 14.77), (150, 25.51), (250, 35.55), (350, 43.59),
                         (500, 63.04), (700, 57.1)),
        "real-benelux": ((6, 3.37), (18, 8.53), (38, 11.45), (76, 16.18), (150, 27.26), (250, 42.54), (350, 53.79),
                         (500, 70.0), (700, 85.09)),
        "*": ((6, 3.1), (18, 7.74), (38, 11.96), (76, 14.98), (150, 21.44), (250, 45.87), (350, 44.01), (500, 53.31),
              (700, 44.72)),
    },
}


def value_map(base: str, world: str) -> tuple[tuple[int, float], ...]:
    """The knots of ``base``'s critic in ``world`` (a name, ``-vN`` ignored): its own, else pooled, else none."""
    maps = VALUE_MAPS.get(base, {})
    return maps.get(re.sub(r"-v\d+$", "", world), maps.get("*", ()))


def value_slope(knots: tuple[tuple[int, float], ...], left: int) -> float:
    """The slope of a value map at ``left`` steps left (0 without knots: the H steps alone)."""
    if not knots:
        return 0.0
    return float(np.interp(left, [k for k, _ in knots], [b for _, b in knots]))


# how the network plays the futures: "greedy" (the search's), "sample" (its sampling mode, as the network's own rollout
# plays them: an ablation, benchmarks/search_budget.py's ":sample")
FUTURES = ("greedy", "sample")
SE_FLOOR = 1e-6  # summed NSW; a decision's differences are about 0.01-1


def knob(name: str, value: Any) -> int | float:
    """``value`` as a search knob (:data:`KNOBS`); ValueError of one line naming the knob and what is allowed."""
    what, allowed = KNOBS[name]
    if name == "z":
        return positive("search", name, value, what, allowed)
    return whole("search", name, value, what, 2 if name == "K" else 1, allowed)


def budget(name: str) -> tuple[int, int, int, int, float]:
    """The (K, H, R, top, z) of a budget preset; ValueError of one line naming the presets otherwise."""
    if name not in BUDGETS:
        raise ValueError(f"search budget {name!r} is not allowed; allowed: {', '.join(BUDGETS)}")
    return BUDGETS[name]


def candidates(own: np.ndarray, logits: np.ndarray, mask: np.ndarray, top: int) -> list[list[int]]:
    """Per environment: its own action first, then the most probable other allowed actions, ``top`` in all."""
    out = []
    for b in range(len(own)):
        order = [int(a) for a in np.argsort(-logits[b], kind="stable") if mask[b, a] and a != own[b]]
        out.append([int(own[b])] + order[: top - 1])
    return out


def beyond_noise(score: np.ndarray, z: float) -> tuple[int, np.ndarray, np.ndarray]:
    """The candidate to play from ``score`` (C, K), row 0 the network's own, and each row's paired mean and s.e.

    A candidate c > 0 qualifies when the mean over the K worlds of ``score[c] - score[0]``
    exceeds ``z`` times its standard error (and 0); the qualifying one with the largest mean
    wins, else row 0. The standard error is at least :data:`SE_FLOOR`: a difference that came
    out the same in all K worlds is still K samples, and a huge z then keeps the network's own.
    """
    d = score - score[:1]
    mean = d.mean(1)
    se = np.maximum(d.std(1, ddof=1) / math.sqrt(d.shape[1]), SE_FLOOR)
    ok = (mean > z * se) & (mean > 0)
    ok[0] = False
    return (int(np.argmax(np.where(ok, mean, -np.inf))) if ok.any() else 0), mean, se


class NetworkSearch(NetworkRollout):
    """Search with the network ``base`` on K sampled futures of H steps, ended at its value (module docstring).

    Args:
        base: a :class:`~wfbench.policies.neural.policy.NetworkPolicy` deciding all three decisions
            (``policies.get("scalefree-general")``); at the root it acts in its own mode.
        K, H, R, top, z: the knobs (:data:`KNOBS`); None takes the ``budget`` preset's.
        budget: a preset of :data:`BUDGETS`.
        value: the map of the critic into summed NSW, (steps left, slope) knots; None:
            :func:`value_map` of the base's name and the world's (set at the first observation);
            ``()`` (and a base without a map): the H steps alone.
        scenario, seed, name: as :class:`NetworkRollout`.
        futures: how the network plays the futures, :data:`FUTURES` (``"sample"`` is the
            ablation of the greedy futures).
        decide: as :class:`NetworkRollout`; ``"auto"`` (the default): on a world as large as
            ``city`` it deliberates every R steps only (docs/policies.md, "search-scalefree-general"),
            elsewhere where the network hires or lets go and every R steps.
        propose: a second proposer, a deployable policy deciding workforce and positioning
            (``policies.get("solver-tuned")``): it acts on every observation beside the network,
            and at each deliberation its workforce action (with its positioning) joins the
            candidates where it is not among them. None (the default): the network's only.
        propose_asks: with ``propose``, also deliberate where the proposer hires or lets go
            (else only where the network asks and every R steps).
    """

    def __init__(self, base: Any, K: int | None = None, H: int | None = None, R: int | None = None,
                 top: int | None = None, z: float | None = None, budget: str = DEFAULT_BUDGET,
                 value: tuple[tuple[int, float], ...] | None = None, scenario: ScenarioConfig | None = None,
                 seed: int = 0, name: str | None = None, futures: str = "greedy", decide: str = "auto",
                 propose: Any | None = None, propose_asks: bool = False):
        if futures not in FUTURES:
            raise ValueError(f"search futures {futures!r} is not allowed; allowed: {', '.join(FUTURES)} (how the "
                             "network plays the sampled worlds)")
        preset = globals()["budget"](budget)
        given = dict(zip(KNOBS, (K, H, R, top, z), strict=True))
        k, h, r, self.top, self.z = (knob(n, preset[i] if v is None else v) for i, (n, v) in enumerate(given.items()))
        super().__init__(base, k, h, r, scenario=scenario, seed=seed,
                         name=name or f"search-{getattr(base, 'name', 'network')}", decide=decide)
        self.futures = futures
        self.value_given = None if value is None else tuple(value)
        self.value = self.value_given
        self.last_test: dict[int, tuple[list[int], np.ndarray, np.ndarray]] = {}
        if propose is not None and not {"workforce", "positioning"} <= set(getattr(propose, "decisions", ())):
            raise ValueError(f"search proposer {getattr(propose, 'name', propose)!r} does not decide workforce and "
                             "positioning; allowed: a deployable policy deciding both, such as solver-tuned")
        self.propose = propose
        self.propose_asks = bool(propose_asks)
        self.proposed: dict[str, np.ndarray] | None = None
        self.last_theirs: dict[int, int] = {}  # at the last deliberation: environment -> the proposer's candidate

    def settings(self) -> dict[str, Any]:
        out = {**super().settings(), "top": self.top, "z": self.z, "futures": self.futures}
        if self.propose is not None:
            out["propose"] = getattr(self.propose, "name", type(self.propose).__name__)
            out["propose_asks"] = self.propose_asks
        return out

    def reset(self, seeds) -> None:
        super().reset(seeds)
        if self.propose is not None:
            self.propose.reset(self._seeds)

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if self.propose is not None:  # every step, so that its own state follows the episode
            self.proposed = {k: np.asarray(v) for k, v in self.propose.act(obs).items()}
        return super().act(obs)

    def _asks(self, obs: dict[str, np.ndarray], action: dict[str, np.ndarray]) -> np.ndarray:
        asks = super()._asks(obs, action)
        if self.proposed is None or not self.propose_asks:
            return asks
        return asks | (self.proposed["workforce"] != 0)

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        from wfbench.policies.neural.policy import NetworkPolicy

        super()._start(obs)
        if self.value_given is None:
            world = self.config.name if self.config is not None else ""
            self.value = value_map(getattr(self.base, "name", ""), world)
        b = self.base
        self.player = NetworkPolicy(b.model, mode=self.futures, device=str(b.device), seed=b.seed,
                                    name=f"{self.name}/{self.futures}", threads=b.threads)
        self.timing["deviations"] = 0.0

    def _heads_before(self, obs: dict[str, np.ndarray]) -> tuple[dict, dict]:
        """The network's head outputs and features on ``obs`` from its memory before this step's act."""
        p = self.player
        p._state, p._starts = self._prior
        out, x, _ = p.heads(obs)
        return out, x

    def _positions(self, out: dict, x: dict, envs: np.ndarray) -> np.ndarray:
        """(len(envs), 2) the network's greedy facility for a hire (row 0) and a let-go (row 1) of each environment."""
        import torch

        model = self.base.model
        rows = torch.as_tensor(envs)
        with torch.no_grad():
            if "positioning" in out:  # the networks before the scale-free one: (B, 2, M) logits
                logits = out["positioning"][rows].float()
            else:
                logits = torch.stack([model.positioning(out, rows, torch.full_like(rows, w)).float()
                                      for w in (0, 1)], 1)
            mask = x["fac_mask"][rows].bool()[:, None, :].expand_as(logits)
            return logits.masked_fill(~mask, -torch.inf).argmax(-1).numpy()

    def _decide(self, obs, envs: np.ndarray, action: dict[str, np.ndarray], t: int) -> None:
        """:meth:`_search` under the network's torch threads, as its own act (torch's default: every core)."""
        import torch

        threads = self.base.threads
        if threads is None or self.base.device.type != "cpu":
            return self._search(obs, envs, action, t)
        before = torch.get_num_threads()
        torch.set_num_threads(threads)
        try:
            return self._search(obs, envs, action, t)
        finally:
            torch.set_num_threads(before)

    def _search(self, obs, envs: np.ndarray, action: dict[str, np.ndarray], t: int) -> None:
        """Score the candidates of ``envs`` on K greedy futures cut at the value; play a winner beyond the noise."""
        import torch

        w = action["workforce"]
        with torch.no_grad():
            out, x = self._heads_before(obs)
        logits = out["workforce"].float().numpy()
        cands = candidates(w[envs], logits[envs], np.asarray(obs["workforce_mask"])[envs], self.top)
        pos = self._positions(out, x, envs)
        M = action["positioning"].shape[-1]
        theirs = {}  # environment -> the proposer's candidate index (its action is last), where it adds one
        if self.proposed is not None:
            for b, cs in zip(envs, cands, strict=True):
                a = int(self.proposed["workforce"][b])
                if a not in cs and obs["workforce_mask"][b, a]:
                    cs.append(a)
                    theirs[int(b)] = len(cs) - 1
        rows_env, rows_a, rows_k, first_p = [], [], [], []
        for i, (b, cs) in enumerate(zip(envs, cands, strict=True)):
            for j, a in enumerate(cs):
                if j == 0:  # the network's own action keeps its own positioning (sampled in its mode)
                    p_row = action["positioning"][b]
                elif theirs.get(int(b)) == j:  # the proposer's action keeps its positioning
                    p_row = np.asarray(self.proposed["positioning"][b], dtype=action["positioning"].dtype)
                else:
                    p_row = np.zeros((2, M))
                    p_row[int(a >= 4), pos[i, int(a >= 4)]] = 1.0
                for k in range(self.K):
                    rows_env.append(int(b))
                    rows_a.append(a)
                    rows_k.append(k)
                    first_p.append(p_row)
        n = len(rows_env)
        env_idx = np.asarray(rows_env, dtype=np.int64)
        first = {"dispatch": action["dispatch"][env_idx], "workforce": np.asarray(rows_a, dtype=np.int64),
                 "positioning": np.stack(first_p)}
        rngs = None  # greedy: no noise; sampled futures (the ablation) share world k's noise, as the rollout's
        if self.futures == "sample":
            rngs = [np.random.default_rng([int(self._seeds[e]), self.seed, PURPOSE_NOISE, t, k])
                    for e, k in zip(rows_env, rows_k, strict=True)]
        total, fobs, steps = self._play(env_idx, rows_k, first, t, rngs)
        p = self.player
        slope = value_slope(self.value, self.horizon - t - steps)
        if t + steps < self.horizon and slope:  # truncated: the critic's estimate of the rest, in summed NSW
            with torch.no_grad():
                total = total + slope * p.heads(fobs)[0]["value"].float().numpy()
        self.timing["decisions"] += len(envs)
        self.timing["rolls"] += n
        self.last_scores = np.full((self.B, 7), np.nan)
        self.last_test = {}
        self.last_theirs = theirs
        at = 0
        for i, (b, cs) in enumerate(zip(envs, cands, strict=True)):
            score = np.asarray(total[at: at + len(cs) * self.K], dtype=np.float64).reshape(len(cs), self.K)
            at += len(cs) * self.K
            best, mean, se = beyond_noise(score, self.z)
            self.last_scores[b, cs] = score.mean(1)
            self.last_test[int(b)] = (cs, mean, se)
            if best:
                a = cs[best]
                w[b] = a
                if theirs.get(int(b)) == best:
                    action["positioning"][b] = self.proposed["positioning"][b]
                    self.timing["proposed"] = self.timing.get("proposed", 0.0) + 1
                else:
                    action["positioning"][b] = 0.0
                    action["positioning"][b, int(a >= 4), pos[i, int(a >= 4)]] = 1.0
                self.timing["deviations"] += 1


def make(base: Any, budget_name: str = DEFAULT_BUDGET, name: str | None = None, **knobs: Any) -> NetworkSearch:
    """A :class:`NetworkSearch` of ``base`` at a budget preset, knobs overriding it."""
    return NetworkSearch(base, budget=budget_name, name=name, **knobs)


__all__ = ["BUDGETS", "KNOBS", "VALUE_MAPS", "NetworkSearch", "beyond_noise", "budget", "candidates", "knob", "make",
           "value_map", "value_slope"]
