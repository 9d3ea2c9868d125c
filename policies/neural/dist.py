"""The action distributions of the model's heads: masks, sampling, log-probabilities and entropies.

Dispatch is a categorical per facility over the N people plus the no-op, in slot order, a
person picked earlier masked for later facilities (no action names one person twice);
workforce a categorical over the 2L + 1 codes; positioning a pointer per row, of which only the
row the step's workforce action uses counts. Sampling is Gumbel-max with noise from the caller
(``noise``; ``None``: argmax). The rules and why: ``docs/rl.md``, "The action distributions".
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

NEG = -1e9


def _masked(logits: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    return logits.masked_fill(~mask, NEG)


def _safe_rows(mask: torch.Tensor) -> torch.Tensor:
    """At least one allowed entry per row (entry 0 when none is), so a row is always a distribution."""
    none = ~mask.any(-1, keepdim=True)
    first = torch.zeros_like(mask)
    first[..., 0] = True
    return mask | (none & first)


def gumbel(shape, generator: torch.Generator | None = None, device="cpu") -> torch.Tensor:
    u = torch.rand(shape, generator=generator, device=device).clamp_(1e-10, 1.0 - 1e-7)
    return u.log_().neg_().log_().neg_()  # -log(-log(u)) in place: the same bits, no temporaries


def noise_shapes(B: int, M: int, N: int) -> dict[str, tuple[int, ...]]:
    return {"dispatch": (B, M, N + 1), "workforce": (B, 7), "positioning": (B, 2, M)}


def choosing(x: dict) -> torch.Tensor:
    """(B, M) bool: the facilities with a real dispatch choice, an open request and someone free to send."""
    mask = x["dispatch_mask"]
    return x["requesting"] & mask[..., :mask.shape[-1] - 1].any(-1)


def pick_in_slot_order(logits: torch.Tensor, allowed: torch.Tensor, valid: torch.Tensor, cand: torch.Tensor,
                       rows: torch.Tensor, R: int, N: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The dispatch picks of C choosing facilities, each in turn excluding the people taken before it.

    ``logits`` (C, K + 1), noise added, of the facilities in slot order within each
    environment (``rows`` (C,), its environment among ``R``); ``cand`` (C, K) the person
    of each of the K columns, ``valid`` (C, K) which may be sent; column K is the no-op.
    ``allowed`` (C, K + 1), no-op column set, is filled with the mask each pick was made
    under. The rule is sequential, computed without a loop over facilities: every facility
    picks at once, and the picks up to the first repeated person of each environment
    stand; the rest pick again without the people taken (as many rounds as repeats,
    usually one). Masking a person that is not the argmax does not move the argmax, so
    the picks are those of the facility-by-facility rule.
    Returns the picks as column (C,) and as person (C,), N for nobody.
    """
    C, K = cand.shape
    dev = cand.device
    pick = torch.full((C,), K, dtype=torch.long, device=dev)
    person = torch.full((C,), N, dtype=torch.long, device=dev)
    taken = torch.zeros((R, N + 1), dtype=torch.bool, device=dev)
    todo = torch.ones(C, dtype=torch.bool, device=dev)
    while bool(todo.any()):
        e = todo.nonzero(as_tuple=True)[0]
        re = rows[e]
        allowed[e, :K] = valid[e] & ~taken[re[:, None], cand[e]]
        j = _masked(logits[e], allowed[e]).argmax(-1)
        p = torch.where(j < K, cand[e].gather(-1, j.clamp_max(K - 1)[:, None]).squeeze(-1), torch.full_like(j, N))
        firstpick = torch.full((R * (N + 1),), C, dtype=torch.long, device=dev)
        key = re * (N + 1) + p
        firstpick.scatter_reduce_(0, key, e, reduce="amin")
        dup = (p < N) & (firstpick[key] < e)  # an earlier facility of the environment picked the same person
        stop = torch.full((R,), C, dtype=torch.long, device=dev)
        stop.scatter_reduce_(0, re[dup], e[dup], reduce="amin")
        ok = e < stop[re]
        acc = e[ok]
        pick[acc], person[acc] = j[ok], p[ok]
        taken[re[ok], p[ok]] = True
        todo[acc] = False
    return pick, person


@torch.no_grad()
def sample(out: dict, x: dict, noise: dict | None, at: tuple[torch.Tensor, torch.Tensor] | None = None
           ) -> dict[str, torch.Tensor]:
    """Actions from the head outputs: dispatch (B, M) int64, workforce (B,), positioning index (B, 2).

    ``noise``: Gumbel noise per head (shapes of :func:`noise_shapes`); ``None`` is greedy.
    ``at``: None, or the choosing facilities ``choosing(x).nonzero(as_tuple=True)`` when
    the dispatch logits and noise hold only their rows, (C, N + 1) (``WorkforceNet.heads``).
    """
    acts: dict[str, torch.Tensor] = {}
    if "dispatch" in out:
        logits = out["dispatch"].float()  # the noise is added to the choosing facilities' rows alone
        mask = x["dispatch_mask"]
        B, M = mask.shape[:2]
        N = mask.shape[-1] - 1
        act = torch.full((B, M), N, dtype=torch.long, device=logits.device)
        extra = None if noise is None else noise["dispatch"]
        if at is None:  # the whole block: take the choosing facilities' rows (row-major: slot order in an environment)
            at = choosing(x).nonzero(as_tuple=True)
            logits, extra = logits[at], None if extra is None else extra[at]
        rows, facs = at
        if rows.numel():
            lg = logits if extra is None else logits + extra
            allowed = torch.zeros_like(lg, dtype=torch.bool)
            allowed[:, N] = True
            everyone = torch.arange(N, device=lg.device).expand(rows.numel(), N)
            act[rows, facs] = pick_in_slot_order(lg, allowed, mask[rows, facs, :N], everyone, rows, B, N)[1]
        acts["dispatch"] = act
    if "workforce" in out:
        logits = out["workforce"].float()
        if noise is not None:
            logits = logits + noise["workforce"]
        acts["workforce"] = _masked(logits, _safe_rows(x["workforce_mask"])).argmax(-1)
    if "positioning" in out:
        logits = out["positioning"].float()
        if noise is not None:
            logits = logits + noise["positioning"]
        fm = _safe_rows(x["fac_mask"])[:, None, :].expand_as(logits)
        acts["positioning"] = _masked(logits, fm).argmax(-1)  # (B, 2)
    return acts


def _dispatch_logp_ent(logits: torch.Tensor, mask: torch.Tensor, act: torch.Tensor):
    """Log-probability and entropy (B,) of the dispatch actions, summed over the facilities.

    Only the facilities with a real choice (an allowed person) count: about one in seventy
    on ``paper-64``, so the softmax runs on those rows alone, not on the (B, M, N + 1)
    block. "Taken before" is then an exclusive cumulative sum of the picks within each
    environment's choosing facilities, in slot order (the others pick the no-op).
    The sums go through a dense (B, M) scatter, not an accumulating one: deterministic
    on CPU and CUDA.
    """
    B, M, N1 = logits.shape
    N = N1 - 1
    rows, facs = mask[..., :N].any(-1).nonzero(as_tuple=True)  # row-major: slot order within an environment
    if rows.numel() == 0:
        zero = logits.new_zeros(B)
        return zero, zero.clone()
    a = act[rows, facs]
    picks = F.one_hot(a, N1).to(torch.int32)
    picks[:, N] = 0
    before = torch.cumsum(picks, 0) - picks  # picks of every earlier choosing facility, any environment
    first = torch.searchsorted(rows, rows)  # the first choosing facility of the same environment
    taken = (before - before[first]) > 0
    allowed = mask[rows, facs] & ~taken
    allowed[:, N] = True  # the no-op is always allowed
    lp, e = _cat_logp_ent(logits[rows, facs], allowed, a)
    per_fac = logits.new_zeros(2, B, M)
    per_fac[0, rows, facs] = lp
    per_fac[1, rows, facs] = e
    return per_fac[0].sum(-1), per_fac[1].sum(-1)


def _cat_logp_ent(logits, mask, index):
    logp_all = torch.log_softmax(_masked(logits, mask), -1)
    logp = logp_all.gather(-1, index[..., None]).squeeze(-1)
    p = logp_all.exp()
    ent = -(p * logp_all.masked_fill(~mask, 0.0)).sum(-1)
    return logp, ent


def head_log_prob_entropy(out: dict, x: dict, acts: dict) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
    """Per head of ``out``: the log-probability (B,) of its stored action and its entropy (B,)."""
    heads = {}
    if "dispatch" in out:
        heads["dispatch"] = _dispatch_logp_ent(out["dispatch"].float(), x["dispatch_mask"], acts["dispatch"])
    if "workforce" in out:
        heads["workforce"] = _cat_logp_ent(out["workforce"].float(), _safe_rows(x["workforce_mask"]),
                                           acts["workforce"])
    if "positioning" in out:
        logits = out["positioning"].float()
        fm = _safe_rows(x["fac_mask"])[:, None, :].expand_as(logits)
        lp, e = _cat_logp_ent(logits, fm, acts["positioning"])  # (B, 2)
        w = acts["workforce"]
        use = torch.stack([(w >= 1) & (w <= 3), w >= 4], -1).to(lp.dtype)  # the row this step uses
        heads["positioning"] = ((lp * use).sum(-1), (e * use).sum(-1))
    return heads


def log_prob_entropy(out: dict, x: dict, acts: dict) -> tuple[torch.Tensor, torch.Tensor, dict]:
    """Joint log-probability (B,) of the stored actions, the joint entropy (B,), and the entropy per head."""
    heads = head_log_prob_entropy(out, x, acts)
    logp = sum(lp for lp, _ in heads.values())
    ent = sum(e for _, e in heads.values())
    return logp, ent, {k: e for k, (_, e) in heads.items()}


def positioning_weights(index: torch.Tensor, M: int) -> torch.Tensor:
    """(B, 2, M) weights: 1 on the chosen facility of each row."""
    return F.one_hot(index, M).to(torch.float64)


def env_action(acts: dict[str, torch.Tensor], M: int) -> dict[str, np.ndarray]:
    """The simulator's action of the sampled heads present in ``acts``.

    Dispatch and workforce as int64 indices, positioning as its (B, 2, M) weights.
    """
    out = {k: acts[k].cpu().numpy().astype(np.int64) for k in ("dispatch", "workforce") if k in acts}
    if "positioning" in acts:
        out["positioning"] = positioning_weights(acts["positioning"], M).cpu().numpy()
    return out
