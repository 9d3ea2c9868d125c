"""Several trained networks deciding as one: their heads' logits averaged (issue #52).

A learned policy can spend compute at decision time without a model of the world: run every
training seed of a method and act on their consensus. :class:`EnsembleNet` holds scale-free
networks of one configuration (the training seeds of ``scalefree-general``), feeds each the
same features, keeps each one's own memory, and averages their logits head by head:
workforce, dispatch (per choosing facility and candidate) and positioning. Averaged logits
sample from the normalized geometric mean of the members' distributions (a product of
experts): where they agree it is each of them, where they disagree it is flatter among what
they disagree on and sharper against what all of them rule out. The value is the members'
mean. Sampling, the masks and the noise stream are the scale-free network's, so a
:class:`~wfbench.policies.neural.policy.NetworkPolicy` of an ensemble acts like one of a
network, in every mode, at about the members' count times its cost.

Why, and what it measured: docs/rl.md, "An ensemble of the training seeds".
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import torch
from torch import nn
from wfbench.policies.neural.scalefree import ARCH, ScaleFreeNet

# the heads whose logits are averaged in forward (positioning is averaged where it is asked, in positioning)
AVERAGED = ("value", "workforce", "dispatch")


class EnsembleNet(nn.Module):
    """Scale-free networks of one configuration acting on their averaged logits (module docstring)."""

    def __init__(self, members: Sequence[ScaleFreeNet]):
        super().__init__()
        if not members:
            raise ValueError("an ensemble needs at least one network; "
                             "allowed: scale-free networks of one configuration")
        configs = {json.dumps(m.config.to_dict(), sort_keys=True) for m in members}
        if any(not isinstance(m, ScaleFreeNet) for m in members) or len(configs) != 1:
            raise ValueError(f"an ensemble's networks must be {ARCH} networks of one configuration; "
                             f"got {len(members)} networks of {len(configs)} configurations")
        self.members = nn.ModuleList(members)
        self.config = members[0].config

    def initial_state(self, B: int, device=None) -> tuple:
        return tuple(m.initial_state(B, device) for m in self.members)

    def featurize(self, raw: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        return self.members[0].featurize(raw)

    def noise_shapes(self, B: int, M: int, N: int) -> dict[str, tuple[int, ...]]:
        return self.members[0].noise_shapes(B, M, N)

    def forward(self, x: dict[str, torch.Tensor], state: tuple, starts: torch.Tensor):
        """Every member's step on the same features; the averaged heads and each member's own outputs."""
        outs, states = [], []
        for m, s in zip(self.members, state, strict=True):
            o, s2 = m(x, s, starts)
            outs.append(o)
            states.append(s2)
        out = {k: torch.stack([o[k] for o in outs]).mean(0) for k in AVERAGED}
        out["members"] = outs
        return out, tuple(states)

    def positioning(self, out: dict, rows: torch.Tensor, which: torch.Tensor) -> torch.Tensor:
        """The members' positioning logits (n, M), averaged."""
        return torch.stack([m.positioning(o, rows, which)
                            for m, o in zip(self.members, out["members"], strict=True)]).mean(0)

    # the scale-free network's distributions read only the heads' logits, the masks and positioning above
    _dispatch_masks = ScaleFreeNet._dispatch_masks
    sample = ScaleFreeNet.sample
    log_prob_entropy = ScaleFreeNet.log_prob_entropy
    dispatch_label_log_probs = ScaleFreeNet.dispatch_label_log_probs


__all__ = ["AVERAGED", "EnsembleNet"]
