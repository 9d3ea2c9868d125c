"""A critic for the search's futures, fitted on the play they are played with (issue #52).

PPO's critic (``value``) predicts the shaped, discounted return of the network's *sampled*
play in each training world's own units; the search (:mod:`wfbench.policies.lookahead.search`)
maps it into summed NSW by a slope per steps left (``VALUE_MAPS``). Held out the search then
hires where the critic misjudges one more person (docs/policies.md, "Where it loses held out").

:class:`FuturesCritic` is fitted for the job instead: from the network's summary of a step (the
input of its value head, ``top``) and the steps left ``L``, it predicts the mean NSW per step
of the rest of the episode under the network's **greedy** play (what a search's future plays
after its cut), on states the network reaches by its sampled play and then greedy play (what
a search's futures see at their end). Its units are NSW per step on every world, so it needs no
map. ``benchmarks/futures_critic.py`` collects, fits and measures it on the training split only;
the held-out worlds are never fitted.

:class:`CriticSearch` is :class:`~wfbench.policies.lookahead.search.NetworkSearch` with the
future's end scored by it: ``NSW over the H steps + L x critic(top, L)``. Everything else (the
candidates, greedy futures, common random numbers, the noise test) is the search's own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from wfbench.policies.lookahead.search import NetworkSearch

# every steps left: slope 1, so that the search adds the critic's estimate of the rest as it is (summed NSW)
IDENTITY_MAP = ((0, 1.0), (1_000_000, 1.0))


def _torch():
    import torch

    return torch


def left_features(left, horizon):
    """(rows, 2) the steps-left inputs: the share of the episode left and log(1 + L) / 7.

    ``horizon``: the episode's length, one for every row or one per row.
    """
    torch = _torch()
    left = torch.as_tensor(left, dtype=torch.float32).reshape(-1, 1)
    return torch.cat([left / torch.as_tensor(horizon, dtype=torch.float32).reshape(-1, 1), torch.log1p(left) / 7.0],
                     -1)


class FuturesCritic:
    """mean NSW per step of the rest of the episode ~ MLP(top, steps left); fitted by ``benchmarks/futures_critic.py``.

    Args:
        d_top: the width of the network's summary (its value head's input).
        width: the hidden width.
        seed: the initial weights' torch seed.
    """

    def __init__(self, d_top: int, width: int = 64, seed: int = 0):
        torch = _torch()
        nn = torch.nn
        gen = torch.Generator().manual_seed(seed)
        self.d_top, self.width = int(d_top), int(width)
        self.net = nn.Sequential(nn.Linear(self.d_top + 2, self.width), nn.GELU(), nn.Linear(self.width, self.width),
                                 nn.GELU(), nn.Linear(self.width, 1))
        with torch.no_grad():
            for p in self.net.parameters():
                p.copy_(torch.randn(p.shape, generator=gen) * (1.0 / max(p.shape[-1], 1)) ** 0.5 if p.dim() > 1
                        else torch.zeros(p.shape))
        self.mean = 0.0  # the target's mean: the net fits the rest

    def per_step(self, top, left, horizon):
        """(rows,) the predicted mean NSW per step of the rest (a torch tensor)."""
        torch = _torch()
        x = torch.cat([torch.as_tensor(top, dtype=torch.float32), left_features(left, horizon)], -1)
        return self.net(x).squeeze(-1) + self.mean

    def state(self) -> dict[str, Any]:
        return {"d_top": self.d_top, "width": self.width, "mean": self.mean, "weights": self.net.state_dict()}

    @classmethod
    def load(cls, path: str | Path) -> FuturesCritic:
        """A critic saved by :meth:`save`; ValueError of one line if the file is not one."""
        torch = _torch()
        got = torch.load(Path(path), map_location="cpu", weights_only=True)
        if not isinstance(got, dict) or not {"d_top", "width", "mean", "weights"} <= set(got):
            raise ValueError(f"{path}: not a futures critic (a file written by FuturesCritic.save)")
        c = cls(int(got["d_top"]), int(got["width"]))
        c.mean = float(got["mean"])
        c.net.load_state_dict(got["weights"])
        c.net.eval()
        return c

    def save(self, path: str | Path) -> None:
        torch = _torch()
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        torch.save(self.state(), Path(path))


class Summary:
    """Keeps the last output of a network's ``top_norm`` (its value head's input) while attached."""

    def __init__(self, model: Any):
        if not hasattr(model, "top_norm"):
            raise ValueError(f"{type(model).__name__} has no top_norm: a futures critic reads the scale-free "
                             "network's summary; allowed: a scale-free network (scalefree-general)")
        self.last = None
        self._handle = model.top_norm.register_forward_hook(self._keep)

    def _keep(self, module, inputs, output) -> None:
        self.last = output.detach()

    def close(self) -> None:
        self._handle.remove()


def tap_values(policy: Any, keep: Any) -> None:
    """Wrap a network policy's ``heads``: ``keep`` gets PPO's critic value, (rows,) numpy, of every step it reads."""
    heads = policy.heads

    def tapped(obs):
        out, x, c = heads(obs)
        keep(out["value"].float().numpy().copy())
        return out, x, c

    policy.heads = tapped


class CriticSearch(NetworkSearch):
    """:class:`NetworkSearch` whose futures end at a :class:`FuturesCritic` (module docstring).

    Args:
        base: the scale-free network the search plays (``policies.get("scalefree-general")``).
        critic: a :class:`FuturesCritic` fitted on ``base``'s play, or the path of one.
        **knobs: as :class:`NetworkSearch` (``value`` is the critic's, so it is not taken).
    """

    def __init__(self, base: Any, critic: FuturesCritic | str | Path, **knobs: Any):
        if "value" in knobs:
            raise ValueError("a critic search scores the futures' end with its critic; allowed: no value knob")
        super().__init__(base, value=IDENTITY_MAP, **knobs)
        self.critic = critic if isinstance(critic, FuturesCritic) else FuturesCritic.load(critic)
        self._summary: Summary | None = None

    def settings(self) -> dict[str, Any]:
        return {**super().settings(), "value": "futures critic"}

    def _start(self, obs: dict[str, np.ndarray]) -> None:
        super()._start(obs)
        if self._summary is not None:
            self._summary.close()
        self._summary = Summary(self.base.model)
        p, heads, horizon = self.player, self.player.heads, self.horizon

        def scored(o):  # the value the search adds at a future's end: the critic's rest, in summed NSW
            torch = _torch()
            out, x, c = heads(o)
            left = horizon - np.asarray(o["t"], dtype=np.int64)
            with torch.no_grad():
                rest = torch.as_tensor(left, dtype=torch.float32) * self.critic.per_step(self._summary.last, left,
                                                                                        horizon)
            return {**out, "value": rest}, x, c

        p.heads = scored


__all__ = ["CriticSearch", "FuturesCritic", "IDENTITY_MAP", "Summary", "left_features", "tap_values"]
