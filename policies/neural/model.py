"""The paper's joint model (section 4, "Joint Model") in torch, and the observation -> tensor step.

:class:`WorkforceNet` is one network for every scenario size: facilities and people are sets of
slots, empty ones masked everywhere. Entity embeddings and positional encoders, attention blocks
(``n_blocks``), an LSTM memory, fusion (``n_fusion``) and fp32 heads: a dispatch pointer, the
workforce codes, a positioning pointer per row, and the value. The heads return raw logits; the
masks are applied by :mod:`wfbench.policies.neural.dist`. :data:`PRESETS` are the ``--model``
sizes, :func:`featurize` builds the inputs (``docs/rl.md``, "The model").
torch is imported here and in the modules that import this one; ``import policies`` never imports it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

# column indices of the observation (docs/policies.md); kept as literals so this module
# needs nothing of the simulator to be imported
FAC_X, FAC_Y, FAC_OPERATIONAL, FAC_REQUESTING, FAC_ASSIGNED, FAC_DOWNTIME = 0, 1, 2, 3, 4, 6
PER_HOME_X, PER_HOME_Y, PER_X, PER_Y, PER_LEVEL, PER_BUSY, PER_HEADING, PER_UTIL = 0, 1, 2, 3, 4, 5, 7, 8
N_STATUS = 6
N_GLOBALS = 12
N_WORKFORCE = 7
N_FAC_IN = 6  # operational, requesting, assigned, downtime, requesting-unassigned, active
N_PER_IN = 3 + 3 + N_STATUS + 2  # level one-hot, busy, heading out, utilization, status one-hot, notice, dispatchable

# the observation keys a rollout stores; the rest (dispatch_mask) is rebuilt from them
OBS_KEYS = ("facilities", "personnel", "facility_mask", "personnel_mask", "personnel_status", "under_notice",
            "dispatchable", "requesting", "globals", "workforce_mask")


@dataclass(frozen=True)
class ModelConfig:
    """Sizes of the network; ``PRESETS`` has the named ones."""

    d: int = 32  # embedding width
    heads: int = 2
    n_blocks: int = 1  # facility/personnel self- and cross-attention blocks
    n_fusion: int = 1  # self-attention layers after the LSTM
    lstm: int = 32  # LSTM hidden size
    ff: int = 2  # feed-forward width multiple
    pos_freqs: int = 4  # Fourier frequencies of the positional encoder
    coord_scale: float = 64.0  # coordinates are divided by this (the largest grid side of the presets)
    decisions: tuple[str, ...] = ("dispatch", "workforce", "positioning")

    def to_dict(self) -> dict:
        return {**asdict(self), "decisions": list(self.decisions)}

    @classmethod
    def from_dict(cls, d: dict) -> ModelConfig:
        return cls(**{**d, "decisions": tuple(d["decisions"])})


PRESETS: dict[str, dict] = {
    "tiny": dict(d=16, heads=2, n_blocks=1, n_fusion=1, lstm=16, ff=2, pos_freqs=2),
    "small": dict(d=32, heads=2, n_blocks=1, n_fusion=1, lstm=32, ff=2, pos_freqs=4),
    "paper": dict(d=64, heads=4, n_blocks=2, n_fusion=1, lstm=64, ff=2, pos_freqs=8),  # ~475k parameters
    # CPU training: no attention (the entities meet only through the pooled summary, the LSTM
    # and the dispatch pointer); about 5x faster than "small" on 2 cores (docs/rl.md)
    "cpu": dict(d=32, heads=2, n_blocks=0, n_fusion=0, lstm=32, ff=2, pos_freqs=4),
}


def model_config(preset: str = "small", decisions: tuple[str, ...] = ("dispatch", "workforce", "positioning"),
                 **overrides) -> ModelConfig:
    if preset not in PRESETS:
        raise ValueError(f"unknown model preset {preset!r}; allowed: {', '.join(PRESETS)}")
    bad = set(decisions) - {"dispatch", "workforce", "positioning"}
    if bad or "dispatch" not in decisions and "workforce" not in decisions:
        raise ValueError(f"decisions {decisions!r}: allowed: a subset of dispatch, workforce, positioning")
    return ModelConfig(**{**PRESETS[preset], **overrides, "decisions": tuple(decisions)})


# -- observation -> tensors ----------------------------------------------------------------
def obs_to_torch(obs: dict, device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
    """The stored keys of a batched observation as tensors (copies: the simulator reuses its buffers)."""
    return {k: torch.from_numpy(np.array(obs[k], copy=True)).to(device, non_blocking=True) for k in OBS_KEYS}


def manhattan(fac_xy: torch.Tensor, per_xy: torch.Tensor) -> torch.Tensor:
    """|dx| + |dy| between facilities (..., M, 2) and people (..., N, 2): (..., M, N).

    On the two coordinates apart, not through a (..., M, N, 2) block: the same bits (a sum
    of two terms is one rounding either way), a third of the memory traffic. Every
    element is its own two subtractions and one sum, so the rows of a subset of
    facilities have the bits of the same rows of the whole block.
    """
    dist = torch.sub(fac_xy[..., :, None, 0], per_xy[..., None, :, 0]).abs_()
    dist += torch.sub(fac_xy[..., :, None, 1], per_xy[..., None, :, 1]).abs_()
    return dist


def featurize(raw: dict[str, torch.Tensor], coord_scale: float, dist: bool = True) -> dict[str, torch.Tensor]:
    """Model inputs from the raw observation tensors (any batch shape B; no loop over environments).

    Returns facility and personnel feature rows, coordinates scaled by ``coord_scale``,
    the boolean masks (``fac_mask``, ``per_mask``, ``dispatch_mask`` (B, M, N + 1) with
    the no-op column always allowed, ``workforce_mask``) and, unless ``dist`` is False,
    the distance between every facility and every person's current position (B, M, N),
    in the same scale. Without it, the network computes the distance rows its dispatch
    head reads (:meth:`WorkforceNet.heads` with ``at``); a network with attention blocks
    needs the whole block.
    """
    fac = raw["facilities"].float()
    per = raw["personnel"].float()
    fac_mask = raw["facility_mask"] > 0
    per_mask = raw["personnel_mask"] > 0
    requesting = raw["requesting"] > 0
    dispatchable = raw["dispatchable"] > 0
    fac_in = torch.stack([fac[..., FAC_OPERATIONAL], fac[..., FAC_REQUESTING], fac[..., FAC_ASSIGNED],
                          fac[..., FAC_DOWNTIME], requesting.float(), fac_mask.float()], -1)
    level = F.one_hot(per[..., PER_LEVEL].long().clamp(0, 2), 3).float() * per_mask[..., None]
    status = F.one_hot(raw["personnel_status"].long().clamp(0, N_STATUS - 1), N_STATUS).float()
    per_in = torch.cat([level, per[..., PER_BUSY:PER_BUSY + 1], per[..., PER_HEADING:PER_HEADING + 1],
                        per[..., PER_UTIL:PER_UTIL + 1], status, raw["under_notice"].float()[..., None],
                        dispatchable.float()[..., None]], -1)
    fac_xy = fac[..., FAC_X:FAC_Y + 1] / coord_scale
    per_xy = per[..., PER_X:PER_Y + 1] / coord_scale
    per_home = per[..., PER_HOME_X:PER_HOME_Y + 1] / coord_scale
    *lead, M = requesting.shape
    dispatch_mask = torch.empty((*lead, M, per.shape[-2] + 1), dtype=torch.bool, device=requesting.device)
    torch.logical_and(requesting[..., :, None], dispatchable[..., None, :], out=dispatch_mask[..., :-1])
    dispatch_mask[..., -1] = True  # the no-op, always allowed
    x = dict(fac_in=fac_in, per_in=per_in, fac_xy=fac_xy, per_xy=per_xy, per_home=per_home,
             glob=raw["globals"].float(), fac_mask=fac_mask, per_mask=per_mask, dispatch_mask=dispatch_mask,
             workforce_mask=raw["workforce_mask"] > 0, requesting=requesting)
    if dist:
        x["dist"] = manhattan(fac_xy, per_xy)
    return x


# -- building blocks -------------------------------------------------------------------------
def _safe_keys(mask: torch.Tensor) -> torch.Tensor:
    """A key mask with at least one key per row (slot 0 when none is valid), so softmax never sees only -inf."""
    none = ~mask.any(-1, keepdim=True)
    first = torch.zeros_like(mask)
    first[..., 0] = True
    return mask | (none & first)


class PositionalEncoder(nn.Module):
    """Non-linear encoder of (x, y): Fourier features, then a two-layer MLP."""

    def __init__(self, d: int, freqs: int):
        super().__init__()
        self.register_buffer("freqs", (2.0 ** torch.arange(freqs)) * math.pi, persistent=False)
        self.mlp = nn.Sequential(nn.Linear(2 + 4 * freqs, d), nn.GELU(), nn.Linear(d, d))

    def forward(self, xy: torch.Tensor) -> torch.Tensor:
        a = xy[..., :, None] * self.freqs  # (..., 2, freqs)
        feats = torch.cat([xy, a.sin().flatten(-2), a.cos().flatten(-2)], -1)
        return self.mlp(feats)


# (device, dtype, q, k, v and mask shapes) of the calls a fused backend refused: they go to the math kernel directly
_MATH_ONLY: set[tuple] = set()


def attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, attn_mask: torch.Tensor) -> torch.Tensor:
    """``F.scaled_dot_product_attention``, with the math kernel where a fused backend refuses the shape.

    On CUDA torch picks cuDNN's attention for bf16 when it can, and cuDNN may refuse a shape
    at run time (``Expected mha_graph.execute(...).is_good() to be true``, issue #44, the
    ``paper`` network at B = 4096). Such a RuntimeError retries the call under
    ``sdpa_kernel(SDPBackend.MATH)`` (the reference kernel, any shape and dtype), and calls of
    the same shapes go there directly from then on. A call that succeeds is the plain
    ``F.scaled_dot_product_attention``: the same bits as before (float32 CPU included).
    A refusal in the backward pass is not caught here.
    """
    key = (q.device.type, q.dtype, tuple(q.shape), tuple(k.shape), tuple(v.shape), tuple(attn_mask.shape))
    if key not in _MATH_ONLY:
        try:
            return F.scaled_dot_product_attention(q, k, v, attn_mask=attn_mask)
        except torch.OutOfMemoryError:
            raise  # not a refusal: the math kernel needs more memory, not less
        except RuntimeError:
            _MATH_ONLY.add(key)
    from torch.nn.attention import SDPBackend, sdpa_kernel

    with sdpa_kernel(SDPBackend.MATH):
        return F.scaled_dot_product_attention(q, k, v, attn_mask=attn_mask)


class Attention(nn.Module):
    """Pre-norm multi-head attention with a key mask and an optional additive bias (B, heads, Lq, Lk)."""

    def __init__(self, d: int, heads: int, ff: int):
        super().__init__()
        self.h = heads
        self.nq, self.nk = nn.LayerNorm(d), nn.LayerNorm(d)
        self.q, self.kv, self.o = nn.Linear(d, d), nn.Linear(d, 2 * d), nn.Linear(d, d)
        self.nf = nn.LayerNorm(d)
        self.ffn = nn.Sequential(nn.Linear(d, ff * d), nn.GELU(), nn.Linear(ff * d, d))

    def forward(self, x, ctx, key_mask, bias=None):
        B, Lq, d = x.shape
        Lk = ctx.shape[1]
        q = self.q(self.nq(x)).view(B, Lq, self.h, -1).transpose(1, 2)
        k, v = self.kv(self.nk(ctx)).view(B, Lk, 2, self.h, -1).permute(2, 0, 3, 1, 4)
        mask = torch.zeros(B, 1, 1, Lk, dtype=q.dtype, device=x.device).masked_fill(
            ~_safe_keys(key_mask)[:, None, None, :], float("-inf"))
        if bias is not None:
            mask = mask + bias.to(q.dtype)
        y = attention(q, k, v, mask)
        x = x + self.o(y.transpose(1, 2).reshape(B, Lq, d))
        return x + self.ffn(self.nf(x))


class Block(nn.Module):
    """Facility-facility and personnel-personnel self-attention, then the two cross-attentions."""

    def __init__(self, d: int, heads: int, ff: int):
        super().__init__()
        self.ff_self, self.pp_self = Attention(d, heads, ff), Attention(d, heads, ff)
        self.fp_cross, self.pf_cross = Attention(d, heads, ff), Attention(d, heads, ff)
        self.dist_bias = nn.Parameter(torch.zeros(heads))  # per head, times the facility-person distance

    def forward(self, fac, per, fac_mask, per_mask, dist):
        fac = self.ff_self(fac, fac, fac_mask)
        per = self.pp_self(per, per, per_mask)
        bias = -self.dist_bias.view(1, -1, 1, 1).abs() * dist[:, None]  # (B, heads, M, N)
        fac2 = self.fp_cross(fac, per, per_mask, bias)
        per2 = self.pf_cross(per, fac, fac_mask, bias.transpose(-1, -2))
        return fac2, per2


def _masked_mean(x, mask):
    m = mask.to(x.dtype)[..., None]
    return (x * m).sum(-2) / m.sum(-2).clamp_min(1.0)


class WorkforceNet(nn.Module):
    """The joint model of the paper (see the module docstring); ``config.decisions`` picks the heads."""

    computes_dispatch_rows = True  # forward(..., at) computes the dispatch rows at alone (heads)

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = c = config
        d = c.d
        self.fac_in = nn.Sequential(nn.Linear(N_FAC_IN, d), nn.GELU(), nn.Linear(d, d))
        self.per_in = nn.Sequential(nn.Linear(N_PER_IN, d), nn.GELU(), nn.Linear(d, d))
        self.glob_in = nn.Sequential(nn.Linear(N_GLOBALS, d), nn.GELU(), nn.Linear(d, d))
        self.fac_pos = PositionalEncoder(d, c.pos_freqs)
        self.per_pos = PositionalEncoder(d, c.pos_freqs)
        self.home_pos = PositionalEncoder(d, c.pos_freqs)
        self.blocks = nn.ModuleList([Block(d, c.heads, c.ff) for _ in range(c.n_blocks)])
        self.summary = nn.Sequential(nn.LayerNorm(3 * d), nn.Linear(3 * d, c.lstm), nn.GELU())
        self.lstm = nn.LSTM(c.lstm, c.lstm)
        self.fuse_fac, self.fuse_per = nn.Linear(d + c.lstm, d), nn.Linear(d + c.lstm, d)
        self.fusion_fac = nn.ModuleList([Attention(d, c.heads, c.ff) for _ in range(c.n_fusion)])
        self.fusion_per = nn.ModuleList([Attention(d, c.heads, c.ff) for _ in range(c.n_fusion)])
        self.out_fac, self.out_per = nn.LayerNorm(d), nn.LayerNorm(d)
        hd = 2 * d + c.lstm
        if "dispatch" in c.decisions:
            self.ptr_q, self.ptr_k = nn.Linear(d, d), nn.Linear(d, d)
            self.ptr_noop = nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, 1))
            # the distance prior of the pointer: logits -= softplus(dist_scale) * distance / coord scale
            self.dist_scale = nn.Parameter(torch.tensor(3.0))
        if "workforce" in c.decisions:
            self.wf_head = nn.Sequential(nn.Linear(hd, d), nn.GELU(), nn.Linear(d, N_WORKFORCE))
        if "positioning" in c.decisions:
            self.pos_head = nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, 2))
        self.value_head = nn.Sequential(nn.Linear(hd, d), nn.GELU(), nn.Linear(d, 1))
        with torch.no_grad():  # small initial logits: a near-uniform start over the allowed actions
            for head in ("wf_head", "pos_head"):
                if hasattr(self, head):
                    getattr(self, head)[-1].weight.mul_(0.01)
                    getattr(self, head)[-1].bias.zero_()
            if hasattr(self, "wf_head"):
                self.wf_head[-1].bias[0] = 4.5  # start with the workforce no-op about 94% of the steps
            if hasattr(self, "ptr_noop"):
                self.ptr_noop[-1].bias.fill_(-4.0)  # start by sending the nearest free person

    def initial_state(self, B: int, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        z = torch.zeros(1, B, self.config.lstm, device=device)
        return z, z.clone()

    # -- the three stages ---------------------------------------------------------------------
    def encode(self, x: dict[str, torch.Tensor]):
        """Entity tokens and the pooled summary of one step (no memory): (F, P, g, z)."""
        fac = self.fac_in(x["fac_in"]) + self.fac_pos(x["fac_xy"])
        per = self.per_in(x["per_in"]) + self.per_pos(x["per_xy"]) + self.home_pos(x["per_home"])
        g = self.glob_in(x["glob"])
        for blk in self.blocks:
            fac, per = blk(fac, per, x["fac_mask"], x["per_mask"], x["dist"])
        z = self.summary(torch.cat([_masked_mean(fac, x["fac_mask"]), _masked_mean(per, x["per_mask"]), g], -1))
        return fac, per, g, z

    def memory(self, z: torch.Tensor, state, starts: torch.Tensor):
        """The LSTM over a sequence: z (T, B, H), starts (T, B) (1: an episode starts here, reset the state).

        In float32 under autocast too (cuDNN's autocast would run it in float16 whatever the
        autocast dtype); in float32 the casts are the tensors themselves: the same bits.
        """
        with torch.autocast(device_type=z.device.type, enabled=False):
            z, (h, c) = z.float(), (s.float() for s in state)
            outs = []
            for t in range(z.shape[0]):
                keep = (1.0 - starts[t].to(z.dtype)).view(1, -1, 1)
                o, (h, c) = self.lstm(z[t:t + 1], (h * keep, c * keep))
                outs.append(o[0])
            return torch.stack(outs), (h, c)

    def heads(self, x: dict[str, torch.Tensor], fac, per, g, mem, at=None) -> dict[str, torch.Tensor]:
        """Fusion of the memory with the entities, then the heads (raw logits, fp32) and the value.

        ``at``: None, or ``(rows, facs)`` index tensors (C,) of the facilities whose
        dispatch row is read; ``dispatch`` is then those rows alone, (C, N + 1), with the
        bits of the same rows of the whole (B, M, N + 1) block. The pointer product stays
        whole (a matrix product of fewer rows may round differently: BLAS picks the
        kernel by shape, benchmarks/pointer_rows.py); the distance, the prior and the
        no-op column are elementwise and are computed on the rows read.
        """
        mem_t = mem.to(fac.dtype)
        fac = self.fuse_fac(torch.cat([fac, mem_t[:, None].expand(-1, fac.shape[1], -1)], -1))
        per = self.fuse_per(torch.cat([per, mem_t[:, None].expand(-1, per.shape[1], -1)], -1))
        for lf, lp in zip(self.fusion_fac, self.fusion_per, strict=True):
            fac, per = lf(fac, fac, x["fac_mask"]), lp(per, per, x["per_mask"])
        fac, per = self.out_fac(fac), self.out_per(per)
        out: dict[str, torch.Tensor] = {}
        with torch.autocast(device_type=fac.device.type, enabled=False):
            fac, per, mem = fac.float(), per.float(), mem.float()
            top = torch.cat([_masked_mean(fac, x["fac_mask"]), _masked_mean(per, x["per_mask"]), mem], -1)
            out["value"] = self.value_head(top).squeeze(-1)
            if hasattr(self, "ptr_q"):
                q, k = self.ptr_q(fac), self.ptr_k(per)
                if at is None:
                    logits, dist, noop = q @ k.transpose(-1, -2) / math.sqrt(q.shape[-1]), x["dist"], self.ptr_noop(fac)
                else:
                    rows, facs = at
                    logits = (q @ k.transpose(-1, -2))[rows, facs] / math.sqrt(q.shape[-1])
                    dist = x["dist"][rows, facs] if "dist" in x else \
                        manhattan(x["fac_xy"][rows, facs][:, None], x["per_xy"][rows])[:, 0]
                    noop = self.ptr_noop(fac)[rows, facs]
                # (softplus * 8) * dist, not (softplus * dist) * 8: a power of two scales exactly, so the same
                # bits forward and backward, with one (B, M, N) product less each way
                logits = logits - (F.softplus(self.dist_scale) * 8.0) * dist
                out["dispatch"] = torch.cat([logits, noop], -1)  # (B, M, N + 1), or (C, N + 1) with at
            if hasattr(self, "wf_head"):
                out["workforce"] = self.wf_head(top)
            if hasattr(self, "pos_head"):
                out["positioning"] = self.pos_head(fac).transpose(-1, -2)  # (B, 2, M)
        return out

    def forward(self, x: dict[str, torch.Tensor], state, starts: torch.Tensor, at=None):
        """A sequence of T steps of B environments, flattened to T * B rows (time major).

        ``state`` is the LSTM state before the first step, ``starts`` (T, B) marks the
        steps where an episode begins, ``at`` the dispatch rows to compute (:meth:`heads`).
        Returns the head outputs (T * B rows) and the final state.
        """
        T, B = starts.shape
        fac, per, g, z = self.encode(x)
        mem, state = self.memory(z.view(T, B, -1), state, starts)
        return self.heads(x, fac, per, g, mem.reshape(T * B, -1), at), state

    @property
    def reads_whole_distance(self) -> bool:
        """Whether the encoder's attention reads the (B, M, N) distance (a bias), beyond the dispatch rows."""
        return len(self.blocks) > 0


@dataclass(frozen=True)
class AgentSetConfig:
    """The networks of ``--agents independent``: one :class:`ModelConfig` per decision."""

    members: tuple[tuple[str, ModelConfig], ...]

    @property
    def decisions(self) -> tuple[str, ...]:
        return tuple(d for d, _ in self.members)

    @property
    def coord_scale(self) -> float:
        return self.members[0][1].coord_scale

    def to_dict(self) -> dict:
        return {"agents": "independent", "members": {d: m.to_dict() for d, m in self.members}}

    @classmethod
    def from_dict(cls, d: dict) -> AgentSetConfig:
        return cls(tuple((k, ModelConfig.from_dict(v)) for k, v in d["members"].items()))


def agent_set_config(preset: str = "cpu", decisions: tuple[str, ...] = ("dispatch", "workforce", "positioning"),
                     **overrides) -> AgentSetConfig:
    """One network of ``preset`` per decision, each with that decision's head alone (and its own value)."""
    if "positioning" in decisions and "workforce" not in decisions:
        raise ValueError("independent agents: positioning needs the workforce agent (it places its hires)")
    model_config(preset, decisions, **overrides)  # checks the preset and the decisions
    return AgentSetConfig(tuple((d, ModelConfig(**{**PRESETS[preset], **overrides, "decisions": (d,)}))
                                for d in decisions))


class AgentSet(nn.Module):
    """Independent agents: one :class:`WorkforceNet` per decision, no shared parameter.

    It runs like a joint network: ``forward`` returns every head (each from its own
    network) and ``out["value"]`` as (rows, A), one critic per agent in ``decisions``
    order; the LSTM state is the members' states side by side on the last axis, so the
    trainer's state handling (clone, select environments, reset) works unchanged. Each
    member sees the whole observation, as every agent of the PettingZoo environment does
    (``wfbench.envs.parallel``), and is trained on the shared reward with its own
    advantage (``wfbench.train.ppo``, ``agents="independent"``).
    """

    def __init__(self, config: AgentSetConfig):
        super().__init__()
        self.config = config
        self.members = nn.ModuleDict({d: WorkforceNet(c) for d, c in config.members})

    def initial_state(self, B: int, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        z = torch.zeros(1, B, sum(m.config.lstm for m in self.members.values()), device=device)
        return z, z.clone()

    computes_dispatch_rows = True  # forward(..., at): its dispatch member computes the rows at alone

    def forward(self, x: dict[str, torch.Tensor], state, starts: torch.Tensor, at=None):
        out: dict[str, torch.Tensor] = {}
        values, hs, cs, lo = [], [], [], 0
        for d, net in self.members.items():
            k = net.config.lstm
            o, (h, c) = net(x, (state[0][..., lo:lo + k], state[1][..., lo:lo + k]), starts, at)
            lo += k
            out[d] = o[d]
            values.append(o["value"])
            hs.append(h)
            cs.append(c)
        out["value"] = torch.stack(values, -1)
        return out, (torch.cat(hs, -1), torch.cat(cs, -1))

    @property
    def reads_whole_distance(self) -> bool:
        return any(net.reads_whole_distance for net in self.members.values())


def network_from_config(d: dict) -> WorkforceNet | AgentSet:
    """The network a checkpoint's ``model_config`` describes: joint or a set of independent agents."""
    if d.get("agents") == "independent":
        return AgentSet(AgentSetConfig.from_dict(d))
    return WorkforceNet(ModelConfig.from_dict(d))


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
