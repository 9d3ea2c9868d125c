"""A network that reads the world as a dispatcher does: observation version 2, any size (``--model scalefree``).

:func:`featurize` reads :func:`wfbench.core.observation_v2.observe_v2`: lengths in travel-time
steps, positions over the world's extent, the public ``context``, never ``units``, so a world
scaled by k shows the same tensors. :class:`ScaleFreeNet` has no attention: entity MLPs, one LSTM
memory per environment, a dispatch pointer over the k nearest eligible people of only the
choosing facilities, and its own action distributions (:meth:`ScaleFreeNet.sample`). Which
observation a network reads is decided here for every network (:func:`raw_tensors`,
:func:`features`, :func:`noise_shapes`, :func:`sample`, :func:`head_log_probs`), so callers do
not tell versions apart. The architecture: ``docs/rl.md``, "The network".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from wfbench.policies.neural import dist
from wfbench.policies.neural.dist import NEG, _cat_logp_ent, _masked, _safe_rows
from wfbench.policies.neural.model import (
    FAC_ASSIGNED,
    FAC_DOWNTIME,
    FAC_OPERATIONAL,
    FAC_REQUESTING,
    N_GLOBALS,
    N_STATUS,
    N_WORKFORCE,
    OBS_KEYS,
    PER_BUSY,
    PER_HEADING,
    PER_HOME_X,
    PER_LEVEL,
    PER_UTIL,
    PER_X,
    _masked_mean,
    network_from_config,
)
from wfbench.policies.neural.model import featurize as featurize_v1
from wfbench.policies.neural.model import obs_to_torch as obs_to_torch_v1

from wfbench.core.observation_v2 import observe_v2

ARCH = "scalefree"
OBS_KEYS_V2 = (*OBS_KEYS, "context")
# the context's columns (wfbench.core.observation_v2.CONTEXT_FEATURES), as literals so this module needs nothing of
# the simulator: which enter as they are (probabilities, salaries, utilization targets); the rest as log(1 + x)
N_CONTEXT = 33
CTX_EXTENT_X, CTX_EXTENT_Y = 0, 1
CTX_REQUEST_RATE, CTX_CHURN_RATE = 10, 11
CTX_AS_IS = (12, 13, 14, 15, 16, 17, 18, 19)  # fix probabilities, salaries, target utilization and tolerance
N_FAC_IN = 7  # operational, requesting, assigned, downtime, requesting-unassigned, active, chooses
N_PER_IN = 3 + 3 + N_STATUS + 2  # level one-hot, busy, heading out, utilization, status one-hot, notice, dispatchable
PAIR_IN = 3  # log(1 + tt), rank / k, (tt - tt_nearest) / (1 + tt_nearest)
CLIP = 10.0


@dataclass(frozen=True)
class ScaleFreeConfig:
    """Sizes of the scale-free network (``--model scalefree``; ``model_overrides`` change any field)."""

    d: int = 32
    lstm: int = 32
    k: int = 8  # candidates per choosing facility: the k nearest eligible people in travel time
    pos_freqs: int = 3  # Fourier frequencies of the positions in [0, 1] (periods 2, 1, 0.5)
    decisions: tuple[str, ...] = ("dispatch", "workforce", "positioning")
    arch: str = ARCH
    obs_version: int = 2

    def to_dict(self) -> dict:
        return {**asdict(self), "decisions": list(self.decisions)}

    @classmethod
    def from_dict(cls, d: dict) -> ScaleFreeConfig:
        return cls(**{**d, "decisions": tuple(d["decisions"])})


def scalefree_config(decisions: tuple[str, ...] = ("dispatch", "workforce", "positioning"),
                     **overrides) -> ScaleFreeConfig:
    if tuple(decisions) != ("dispatch", "workforce", "positioning"):
        raise ValueError(f"the scalefree network decides all three decisions; variant with {decisions} is not "
                         "allowed; allowed: variant joint")
    allowed = {"d", "lstm", "k", "pos_freqs"}
    unknown = set(overrides) - allowed
    if unknown:
        raise ValueError(f"unknown scalefree model setting(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
    for name, v in overrides.items():
        if type(v) is not int or v < 1:
            raise ValueError(f"scalefree model setting {name} = {v!r} is not allowed; allowed: an integer >= 1")
    return ScaleFreeConfig(**overrides)


def obs_version(model: nn.Module) -> int:
    """The observation version a network reads: 2 for the scale-free one, 1 for every network of before."""
    return getattr(model.config, "obs_version", 1)


def build_network(d: dict) -> nn.Module:
    """The network a checkpoint's ``model_config`` describes: scale-free, joint or independent agents."""
    if d.get("arch") == ARCH:
        return ScaleFreeNet(ScaleFreeConfig.from_dict(d))
    return network_from_config(d)


# -- any network, by the observation it reads: what the deployed policy and the trainers call -------------
def raw_tensors(model: nn.Module, obs: dict, device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
    """The observation ``model`` reads, as tensors: version 1, or 2 (:func:`observe_v2`) for the scale-free one."""
    if obs_version(model) == 2:
        return obs_to_torch(observe_v2(obs), device)
    return obs_to_torch_v1(obs, device)


def features(model: nn.Module, raw: dict[str, torch.Tensor], rows_only: bool = False) -> dict[str, torch.Tensor]:
    """The network's inputs of :func:`raw_tensors` (any leading axes).

    ``rows_only``: a version-1 network that will compute only the dispatch rows it reads
    (:func:`compact_rows`) and whose encoder does not read the facility-person distance
    gets no (B, M, N) distance block; it computes the rows it reads.
    """
    if obs_version(model) == 2:
        return model.featurize(raw)
    whole = not (rows_only and _computes_dispatch_rows(model)) or model.reads_whole_distance
    return featurize_v1(raw, model.config.coord_scale, dist=whole)


def _computes_dispatch_rows(model: nn.Module) -> bool:
    """Whether a version-1 network's ``forward(x, state, starts, at)`` computes the dispatch rows ``at`` alone.

    ``WorkforceNet`` and ``AgentSet`` do (``computes_dispatch_rows``); a model of one's own
    with the plain ``forward(x, state, starts)`` (docs/rl.md) gets the whole block as before.
    """
    return getattr(model, "computes_dispatch_rows", False)


def compact_rows(model: nn.Module, x: dict) -> torch.Tensor | None:
    """(B, M) bool: the choosing facilities, whose dispatch rows alone a version-1 network computes.

    ``mask.nonzero(as_tuple=True)`` is the ``at`` of ``WorkforceNet.heads`` and of
    :func:`sample`: row-major, so in slot order within each environment, the order the
    sampler picks in. None for the scale-free network (it works on the choosing facilities
    already), for a network without a dispatch head and for a model of one's own that
    computes the whole block.
    """
    if obs_version(model) == 2 or not _computes_dispatch_rows(model) or "dispatch" not in model.config.decisions:
        return None
    return dist.choosing(x)


def noise_shapes(model: nn.Module, B: int, M: int, N: int) -> dict[str, tuple[int, ...]]:
    """The Gumbel noise per head that sampling ``model``'s actions takes, leading axis B."""
    if obs_version(model) == 2:
        return model.noise_shapes(B, M, N)
    return dist.noise_shapes(B, M, N)


def dispatch_rows(model: nn.Module, x: dict) -> torch.Tensor:
    """(rows, M) bool: the facilities whose dispatch noise :func:`sample` reads (a real choice to make)."""
    if obs_version(model) == 2:
        return x["choose"]
    return dist.choosing(x)


def sample(model: nn.Module, out: dict, x: dict, noise: dict | None, at=None) -> dict[str, torch.Tensor]:
    """The actions of ``model``'s head outputs (``noise`` None: greedy), by its distributions.

    ``at``: the dispatch rows a version-1 network computed alone (:func:`compact_rows`).
    """
    if obs_version(model) == 2:
        return model.sample(out, x, noise)
    return dist.sample(out, x, noise, at)


def head_log_probs(model: nn.Module, out: dict, x: dict, acts: dict) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
    """Per head: the log-probability and the entropy (rows,) of stored actions, by ``model``'s distributions."""
    if obs_version(model) == 2:
        return model.log_prob_entropy(out, x, acts)
    return dist.head_log_prob_entropy(out, x, acts)


# -- observation -> tensors ----------------------------------------------------------------------
def obs_to_torch(obs: dict, device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
    """The stored keys of a version-2 observation as tensors (copies: the simulator reuses its buffers)."""
    return {k: torch.from_numpy(np.array(obs[k], copy=True)).to(device, non_blocking=True) for k in OBS_KEYS_V2}


def _fourier(xy: torch.Tensor, freqs: int) -> torch.Tensor:
    f = (2.0 ** torch.arange(freqs, device=xy.device, dtype=xy.dtype)) * math.pi
    a = xy[..., :, None] * f
    return torch.cat([xy, a.sin().flatten(-2), a.cos().flatten(-2)], -1)


@torch.no_grad()
def featurize(raw: dict[str, torch.Tensor], k: int, pos_freqs: int) -> dict[str, torch.Tensor]:
    """Network inputs of a version-2 observation (any leading axes): entity rows, context, the k candidates.

    Everything is in travel time or a ratio, so a world in other units gives the same
    tensors. The candidates: for each facility with an open unassigned request and
    someone dispatchable (``choose``), the ``k`` dispatchable people nearest in travel
    time (``cand``, N where there are fewer), their travel times ``tt`` and ``cand_valid``;
    computed on the choosing facilities only (memory flat in the slots beyond k).
    """
    fac, per = raw["facilities"].float(), raw["personnel"].float()
    *lead, M, _ = fac.shape
    N = per.shape[-2]
    fac, per = fac.reshape(-1, M, fac.shape[-1]), per.reshape(-1, N, per.shape[-1])
    R = fac.shape[0]
    flat = {key: raw[key].reshape(R, *raw[key].shape[len(lead):]) for key in OBS_KEYS_V2 if key not in
            ("facilities", "personnel")}
    ctx = flat["context"].float()
    fac_mask, per_mask = flat["facility_mask"] > 0, flat["personnel_mask"] > 0
    requesting, dispatchable = flat["requesting"] > 0, flat["dispatchable"] > 0
    extent = ctx[:, [CTX_EXTENT_X, CTX_EXTENT_Y]].clamp_min(1e-6)  # (R, 2) steps of travel across the grid
    fac_tt, per_tt = fac[..., 0:2], per[..., PER_X:PER_X + 2]
    choose = requesting & dispatchable.any(-1, keepdim=True)
    fac_in = torch.cat([torch.stack([fac[..., FAC_OPERATIONAL], fac[..., FAC_REQUESTING], fac[..., FAC_ASSIGNED],
                                     fac[..., FAC_DOWNTIME], requesting.float(), fac_mask.float(), choose.float()],
                                    -1), _fourier(fac_tt / extent[:, None], pos_freqs)], -1)
    level = F.one_hot(per[..., PER_LEVEL].long().clamp(0, 2), 3).float() * per_mask[..., None]
    status = F.one_hot(flat["personnel_status"].long().clamp(0, N_STATUS - 1), N_STATUS).float()
    per_in = torch.cat([level, per[..., PER_BUSY:PER_BUSY + 1], per[..., PER_HEADING:PER_HEADING + 1],
                        per[..., PER_UTIL:PER_UTIL + 1], status, flat["under_notice"].float()[..., None],
                        dispatchable.float()[..., None], _fourier(per_tt / extent[:, None], pos_freqs),
                        _fourier(per[..., PER_HOME_X:PER_HOME_X + 2] / extent[:, None], pos_freqs)], -1)
    as_is = torch.zeros(N_CONTEXT, dtype=torch.bool, device=ctx.device)
    as_is[list(CTX_AS_IS)] = True
    logc = torch.where(as_is, ctx, torch.log1p(ctx.clamp_min(0.0)))
    # a rate per step is small: its reciprocal (the mean interval now) on the log scale instead
    rates = torch.log1p(1.0 / ctx[:, [CTX_REQUEST_RATE, CTX_CHURN_RATE]].clamp_min(1e-6))
    logc = torch.cat([logc[:, :CTX_REQUEST_RATE], rates, logc[:, CTX_CHURN_RATE + 1:]], -1)
    glob = torch.cat([flat["globals"].float(), logc], -1)
    # the candidates of the choosing facilities
    kk = min(k, N)
    cand = torch.full((R, M, kk), N, dtype=torch.long, device=fac.device)
    tt = torch.zeros((R, M, kk), device=fac.device)
    valid = torch.zeros((R, M, kk), dtype=torch.bool, device=fac.device)
    rows, facs = choose.nonzero(as_tuple=True)
    if rows.numel():
        d = (fac_tt[rows, facs][:, None, :] - per_tt[rows]).abs().sum(-1)  # (C, N) travel time
        d = d.masked_fill(~dispatchable[rows], math.inf)
        dk, ik = torch.topk(d, kk, dim=-1, largest=False, sorted=True)
        ok = torch.isfinite(dk)
        cand[rows, facs] = torch.where(ok, ik, torch.full_like(ik, N))
        tt[rows, facs] = torch.where(ok, dk, torch.zeros_like(dk))
        valid[rows, facs] = ok

    def back(t):
        return t.reshape(*lead, *t.shape[1:])

    return {key: back(v) for key, v in dict(
        fac_in=fac_in, per_in=per_in, glob=glob, fac_mask=fac_mask, per_mask=per_mask, choose=choose,
        cand=cand, tt=tt, cand_valid=valid, workforce_mask=flat["workforce_mask"] > 0).items()}


class ScaleFreeNet(nn.Module):
    """The scale-free network (see the module docstring)."""

    def __init__(self, config: ScaleFreeConfig):
        super().__init__()
        self.config = c = config
        d, f4 = c.d, 4 * c.pos_freqs
        self.fac_mlp = nn.Sequential(nn.Linear(N_FAC_IN + 2 + f4, d), nn.GELU(), nn.Linear(d, d))
        self.per_mlp = nn.Sequential(nn.Linear(N_PER_IN + 2 * (2 + f4), d), nn.GELU(), nn.Linear(d, d))
        self.glob_mlp = nn.Sequential(nn.Linear(N_GLOBALS + N_CONTEXT, d), nn.GELU(), nn.Linear(d, d))
        self.summary = nn.Sequential(nn.LayerNorm(3 * d), nn.Linear(3 * d, c.lstm), nn.GELU())
        self.lstm = nn.LSTM(c.lstm, c.lstm)
        hd = 3 * d + c.lstm
        self.top_norm = nn.LayerNorm(hd)
        self.value_head = nn.Sequential(nn.Linear(hd, d), nn.GELU(), nn.Linear(d, 1))
        self.wf_head = nn.Sequential(nn.Linear(hd, d), nn.GELU(), nn.Linear(d, N_WORKFORCE))
        # dispatch: query of a choosing facility (its row and the environment's memory), keys of its candidates
        self.ptr_q = nn.Linear(d, d)
        self.ptr_mem = nn.Linear(c.lstm, d)
        self.ptr_k = nn.Linear(d, d)
        self.pair = nn.Sequential(nn.Linear(PAIR_IN, d), nn.GELU(), nn.Linear(d, 1))
        self.noop = nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, 1))
        # the prior per step of travel: softplus(alpha(context, memory) + alpha_bias)
        self.alpha = nn.Linear(d + c.lstm, 1)
        # positioning: a pointer over facilities for the environments whose workforce action uses it
        self.pos_mem = nn.Linear(c.lstm, d)
        self.pos_head = nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, 2))
        with torch.no_grad():
            for head in (self.wf_head, self.pos_head, self.pair):
                head[-1].weight.mul_(0.01)
                head[-1].bias.zero_()
            self.wf_head[-1].bias[0] = 4.5  # the workforce no-op about 94% of the steps at the start
            self.noop[-1].weight.mul_(0.01)
            self.noop[-1].bias.fill_(-4.0)  # start by sending the nearest free person
            self.alpha.weight.mul_(0.01)
            self.alpha.bias.fill_(math.log(math.expm1(0.1)))  # 0.1 logits per step of travel at the start

    def initial_state(self, B: int, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        z = torch.zeros(1, B, self.config.lstm, device=device)
        return z, z.clone()

    # -- the observation ------------------------------------------------------------------------
    def featurize(self, raw: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        return featurize(raw, self.config.k, self.config.pos_freqs)

    def noise_shapes(self, B: int, M: int, N: int) -> dict[str, tuple[int, ...]]:
        return {"dispatch": (B, M, min(self.config.k, N) + 1), "workforce": (B, N_WORKFORCE), "positioning": (B, 2, M)}

    # -- the network ----------------------------------------------------------------------------
    def forward(self, x: dict[str, torch.Tensor], state, starts: torch.Tensor):
        """T steps of B environments flattened to T * B rows (time major), as :class:`WorkforceNet`.

        Returns the head outputs and the final LSTM state: ``value`` (rows,), ``workforce``
        (rows, 7), ``dispatch`` (C, k + 1) for the choosing facilities in row-major order,
        and what :meth:`positioning` needs (``fac``, ``mem``).
        """
        T, B = starts.shape
        fac = self.fac_mlp(x["fac_in"])
        per = self.per_mlp(x["per_in"])
        g = self.glob_mlp(x["glob"])
        mf, mp = _masked_mean(fac, x["fac_mask"]), _masked_mean(per, x["per_mask"])
        z = self.summary(torch.cat([mf, mp, g], -1)).view(T, B, -1)
        # the memory in float32 under autocast too: cuDNN's autocast would run the LSTM in float16 whatever the
        # autocast dtype (its output then meets bf16 tensors), and the state is carried from step to step
        with torch.autocast(device_type=z.device.type, enabled=False):
            z, (h, c) = z.float(), (s.float() for s in state)
            outs = []
            for t in range(T):
                keep = (1.0 - starts[t].to(z.dtype)).view(1, -1, 1)
                o, (h, c) = self.lstm(z[t:t + 1], (h * keep, c * keep))
                outs.append(o[0])
            mem = torch.stack(outs).reshape(T * B, -1)
        # the heads in float32, as the paper network's (under autocast the entity rows come in bf16, and the
        # positioning head runs after the forward, outside autocast). In float32 .float() is the tensor itself
        # and the autocast context does nothing: the same bits as without it
        with torch.autocast(device_type=fac.device.type, enabled=False):
            fac, per, g, mf, mp, mem = fac.float(), per.float(), g.float(), mf.float(), mp.float(), mem.float()
            top = self.top_norm(torch.cat([mf, mp, g, mem], -1))
            out = {"value": self.value_head(top).squeeze(-1), "workforce": self.wf_head(top), "fac": fac, "mem": mem}
            rows, facs = x["choose"].nonzero(as_tuple=True)
            if rows.numel():
                cand, tt = x["cand"][rows, facs], x["tt"][rows, facs]  # (C, k)
                q = self.ptr_q(fac[rows, facs]) + self.ptr_mem(mem[rows])  # (C, d)
                keys = self.ptr_k(per[rows[:, None], cand.clamp_max(per.shape[1] - 1)])  # (C, k, d)
                near = tt[:, :1]
                kk = tt.shape[1]
                rank = torch.arange(kk, device=tt.device, dtype=tt.dtype).expand_as(tt) / kk
                pair = self.pair(torch.stack([torch.log1p(tt), rank, (tt - near) / (1.0 + near)], -1)).squeeze(-1)
                alpha = F.softplus(self.alpha(torch.cat([g[rows], mem[rows]], -1)))  # (C, 1)
                logits = (keys @ q[:, :, None]).squeeze(-1) / math.sqrt(q.shape[-1]) + pair - alpha * tt
                logits = torch.cat([logits, self.noop(q)], -1)
                out["dispatch"] = CLIP * torch.tanh(logits / CLIP)
            else:
                out["dispatch"] = fac.new_zeros((0, x["cand"].shape[-1] + 1))
        return out, (h, c)

    def positioning(self, out: dict, rows: torch.Tensor, which: torch.Tensor) -> torch.Tensor:
        """Positioning logits (n, M) of environments ``rows``, row ``which`` (0 hire, 1 let go) of each.

        In float32 (a head), called inside autocast or not: ``out`` holds float32 rows (:meth:`forward`).
        """
        with torch.autocast(device_type=out["fac"].device.type, enabled=False):
            fac = out["fac"][rows].float() + self.pos_mem(out["mem"][rows].float())[:, None]
            logits = self.pos_head(fac)  # (n, M, 2)
        return logits.gather(-1, which.view(-1, 1, 1).expand(-1, logits.shape[1], 1)).squeeze(-1)

    # -- the distributions ------------------------------------------------------------------------
    def _dispatch_masks(self, x: dict, rows, facs, persons: torch.Tensor | None, logits: torch.Tensor | None):
        """Per choosing facility, in slot order per environment: its allowed candidates and its pick.

        The rule is sequential (a facility may not take a person an earlier facility of its
        environment took), computed without a loop over facilities. With ``persons`` (C,)
        given (the stored actions): who took each person first is one table lookup. With
        ``logits`` (C, k + 1, noise added) the picks are made here, by
        :func:`dist.pick_in_slot_order` (the rule of every network's dispatch).
        Returns (allowed (C, k + 1), the picks as candidate index (C,), as person (C,)).
        """
        cand, valid = x["cand"][rows, facs], x["cand_valid"][rows, facs]
        C, kk = cand.shape
        N = x["per_in"].shape[-2]
        R = x["choose"].shape[0]
        dev = cand.device
        idx = torch.arange(C, device=dev)
        allowed = torch.zeros((C, kk + 1), dtype=torch.bool, device=dev)
        allowed[:, kk] = True
        if persons is not None:
            first = torch.full((R, N + 1), C, dtype=torch.long, device=dev)  # the entry that took each person
            first[rows, persons] = idx  # a stored action names a person once per environment (N: nobody)
            allowed[:, :kk] = valid & ~(first[rows[:, None], cand] < idx[:, None])
            match = (cand == persons[:, None]) & valid
            pick = torch.where(match.any(-1), match.float().argmax(-1), torch.full_like(idx, kk))
            return allowed, pick, persons
        pick, person = dist.pick_in_slot_order(logits, allowed, valid, cand, rows, R, N)
        return allowed, pick, person

    @torch.no_grad()
    def sample(self, out: dict, x: dict, noise: dict | None) -> dict[str, torch.Tensor]:
        """Actions: dispatch (rows, M) people (N: nobody), workforce (rows,), positioning index (rows, 2)."""
        R, M = x["choose"].shape
        N = x["per_in"].shape[-2]
        rows, facs = x["choose"].nonzero(as_tuple=True)
        act = torch.full((R, M), N, dtype=torch.long, device=x["choose"].device)
        if rows.numel():
            logits = out["dispatch"].float()
            if noise is not None:
                logits = logits + noise["dispatch"][rows, facs]
            _, _, person = self._dispatch_masks(x, rows, facs, None, logits)
            act[rows, facs] = person
        wl = out["workforce"].float()
        if noise is not None:
            wl = wl + noise["workforce"]
        w = _masked(wl, _safe_rows(x["workforce_mask"])).argmax(-1)
        pos = torch.zeros((R, 2), dtype=torch.long, device=w.device)
        use = (w >= 1).nonzero(as_tuple=True)[0]
        if use.numel():
            which = (w[use] >= 4).long()
            pl = self.positioning(out, use, which).float()
            if noise is not None:
                pl = pl + noise["positioning"][use, which]
            pos[use, which] = _masked(pl, _safe_rows(x["fac_mask"][use])).argmax(-1)
        return {"dispatch": act, "workforce": w, "positioning": pos}

    def log_prob_entropy(self, out: dict, x: dict, acts: dict) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        """Per head: the log-probability (rows,) of the stored actions and the entropy (rows,)."""
        R, M = x["choose"].shape
        heads = {}
        rows, facs = x["choose"].nonzero(as_tuple=True)
        zero = out["value"].new_zeros(R).float()
        if rows.numel():
            allowed, pick, _ = self._dispatch_masks(x, rows, facs, acts["dispatch"][rows, facs], None)
            lp, e = _cat_logp_ent(out["dispatch"].float(), allowed, pick)
            per_fac = zero.new_zeros(2, R, M)
            per_fac[0, rows, facs] = lp
            per_fac[1, rows, facs] = e
            heads["dispatch"] = (per_fac[0].sum(-1), per_fac[1].sum(-1))
        else:
            heads["dispatch"] = (zero, zero.clone())
        w = acts["workforce"]
        heads["workforce"] = _cat_logp_ent(out["workforce"].float(), _safe_rows(x["workforce_mask"]), w)
        use = (w >= 1).nonzero(as_tuple=True)[0]
        plp, pe = zero.clone(), zero.clone()
        if use.numel():
            which = (w[use] >= 4).long()
            pl = self.positioning(out, use, which).float()
            idx = acts["positioning"][use].gather(-1, which[:, None]).squeeze(-1)
            lp, e = _cat_logp_ent(pl, _safe_rows(x["fac_mask"][use]), idx)
            plp = plp.index_put((use,), lp)
            pe = pe.index_put((use,), e)
        heads["positioning"] = (plp, pe)
        return heads

    def dispatch_label_log_probs(self, out: dict, x: dict, persons: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per choosing facility (the rows of ``out["dispatch"]``): the log-probability of a label and whether it fits.

        ``persons`` (R, M): a person per facility (N: nobody), as a stored dispatch action.
        A label that names someone outside the facility's k candidates does not fit (False):
        its log-probability is the no-op's, and an imitation loss leaves it out (hindsight
        learning, docs/rl.md). The labels still take their people from the later facilities.
        """
        rows, facs = x["choose"].nonzero(as_tuple=True)
        if not rows.numel():
            empty = out["dispatch"].new_zeros(0).float()
            return empty, empty.bool()
        p = persons[rows, facs]
        allowed, pick, _ = self._dispatch_masks(x, rows, facs, p, None)
        lp, _ = _cat_logp_ent(out["dispatch"].float(), allowed, pick)
        fits = (p >= x["per_in"].shape[-2]) | (pick < allowed.shape[1] - 1)
        return lp, fits


assert NEG < -CLIP  # a masked logit stays below every clipped one
