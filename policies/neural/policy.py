"""A trained checkpoint as a policy: ``policies.get("impala:path/to/ckpt.pt")``, by the algorithm that trained it.

A checkpoint records its algorithm (``algo``: :data:`CHECKPOINT_ALGORITHMS`; none means PPO)
and loads as ``ALGO:PATH``; ``ppo:PATH`` loads any. :class:`NetworkPolicy` follows the policy
protocol (``docs/policies.md``) and acts on the whole batch at once, in mode ``sample`` (the
default: noise from one generator per environment keyed by its seed), ``greedy``,
``greedy-dispatch`` or ``greedy-workforce`` (argmax of that one head, the others sampled).
``trained_on`` is the checkpoint's scenario. A dispatch-only checkpoint is
deployed inside ``policies.Composite`` with ``threshold`` and ``spatial``; independent agents run
each head from its own network. Modes and why: ``docs/rl.md``, "A checkpoint is a policy".
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from wfbench.policies.composite import Composite
from wfbench.policies.neural import ALIAS, CHECKPOINT_ALGORITHMS, scalefree
from wfbench.policies.neural.dist import env_action
from wfbench.policies.neural.model import AgentSet, WorkforceNet
from wfbench.policies.protocol import seeds_array

MODES = ("sample", "greedy", "greedy-dispatch", "greedy-workforce")
POLICY_SEED = 0x99A


def checkpoint_algorithm(ckpt: dict) -> str:
    """The algorithm that wrote ``ckpt`` (``ppo`` for checkpoints written before the key existed)."""
    return ckpt.get("algo", "ppo")


def load_checkpoint(path: str | Path, map_location: str = "cpu") -> dict:
    """The checkpoint dict at ``path``; ``ValueError`` with one line when it is not one."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"checkpoint {str(path)!r} does not exist")
    try:
        ckpt = torch.load(p, map_location=map_location, weights_only=False)
    except Exception as exc:  # noqa: BLE001  (a corrupt or foreign file: say so in one line)
        raise ValueError(f"checkpoint {str(path)!r} cannot be read: {type(exc).__name__}: {exc}") from None
    if not isinstance(ckpt, dict) or "model" not in ckpt or "model_config" not in ckpt:
        raise ValueError(f"{str(path)!r} is not a wfbench checkpoint (no model or model_config)")
    return ckpt


def build_model(ckpt: dict, device: str = "cpu") -> WorkforceNet | AgentSet:
    model = scalefree.build_network(ckpt["model_config"])
    model.load_state_dict(ckpt["model"])
    return model.to(device).eval()


class NetworkPolicy:
    """The network of a checkpoint (of any training algorithm) deciding every decision its heads cover."""

    def __init__(self, model: WorkforceNet | AgentSet, mode: str = "sample", device: str = "cpu", seed: int = 0,
                 name: str = "network", threads: int | None = 1, trained_on: str | None = None):
        if mode not in MODES:
            raise ValueError(f"mode {mode!r} is not allowed; allowed: {', '.join(MODES)}")
        self.model = model.to(device).eval()
        self.mode, self.device, self.seed, self.name = mode, torch.device(device), int(seed), name
        # torch CPU threads during act: an evaluation batch is small, and torch's default (all cores) made
        # two paper-64 episodes take 120 s instead of 15 s when the cores were busy; None keeps torch's setting
        self.threads = threads
        self.decisions = tuple(model.config.decisions)
        # the observation it reads: 1 (the paper's, every network before the scale-free one) or 2 (in travel time)
        self.observation_version = scalefree.obs_version(model)
        # the scenario of its checkpoint: evaluated on another one, the evaluator warns once
        # (wfbench.policies.registry.warn_if_trained_elsewhere)
        self.trained_on = trained_on
        # the sha256 of the checkpoint file it was loaded from (from_checkpoint), which with the mode, seed and
        # threads decides its actions on a batch: the oracle's totals cache keys its episodes by it
        self.checkpoint_sha256: str | None = None
        self._state = None

    def reset(self, seeds: int | Sequence[int]) -> None:
        seeds = seeds_array(seeds)
        self._rngs = [np.random.default_rng([int(s), self.seed, POLICY_SEED]) for s in seeds]
        self._state = self.model.initial_state(len(seeds), self.device)
        self._starts = torch.ones(1, len(seeds), device=self.device)

    def _noise(self, B: int, M: int, N: int, rows: np.ndarray, compact: np.ndarray | None = None
               ) -> dict[str, torch.Tensor]:
        """Gumbel noise of every head, (B, ...) per :func:`scalefree.noise_shapes`, from each environment's generator.

        ``rows`` (B, M) bool: the facilities whose dispatch row the sampler reads (those
        with a real choice). Each generator's stream is laid out as always (the whole
        dispatch block, then the other heads), but the rows nobody reads are skipped with
        ``advance`` and left 0: on ``city`` that is about 97% of a (1,000, 1,001) block per
        environment and step. What is drawn has the same bits as drawing everything (one
        64-bit draw per double, and the transform is elementwise); a test compares.

        ``compact`` (B, M) bool, a superset of ``rows``: the dispatch noise is then only
        those facilities' rows, (C, N + 1) in row-major order, as the network's compact
        dispatch rows (``WorkforceNet.heads`` with ``at``); the stream is the same.
        """
        sizes = {k: s[1:] for k, s in scalefree.noise_shapes(self.model, B, M, N).items()}
        out = {k: np.zeros((B, int(np.prod(s)))) for k, s in sizes.items() if k != "dispatch" or compact is None}
        # the dispatch noise is written one row per (environment, facility): slot[b, f] is its row
        if compact is not None:  # the rows of compact alone, in row-major order
            out["dispatch"] = np.zeros((int(compact.sum()), sizes["dispatch"][-1]))
            slot = np.cumsum(compact.ravel()).reshape(B, M) - 1
        else:  # the whole (B, M * width) block seen as (B * M, width), the same memory
            slot = np.arange(B * M).reshape(B, M)
        for b, rng in enumerate(self._rngs):
            for k, s in sizes.items():
                if k != "dispatch":
                    dst = out[k][b]
                    dst[:] = _gumbel(rng.random(dst.size))
                    continue
                width, at = s[-1], 0
                rows_of = out[k].reshape(-1, width)
                for f in np.flatnonzero(rows[b]):
                    rng.bit_generator.advance(int(f) * width - at)
                    rows_of[slot[b, f]] = _gumbel(rng.random(width))
                    at = (int(f) + 1) * width
                rng.bit_generator.advance(int(np.prod(s)) - at)
        noise = {k: torch.from_numpy(out[k]).float().to(self.device) for k in sizes}
        return {k: v if k == "dispatch" and compact is not None else v.reshape(B, *sizes[k]) for k, v in noise.items()}

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if self._state is None:
            raise RuntimeError("call reset(seeds) before act(obs)")
        if self.threads is None or self.device.type != "cpu":
            return self._act(obs)
        before = torch.get_num_threads()
        torch.set_num_threads(self.threads)
        try:
            return self._act(obs)
        finally:
            torch.set_num_threads(before)

    @torch.no_grad()
    def heads(self, obs: dict[str, np.ndarray]) -> tuple[dict, dict, torch.Tensor | None]:
        """One step of the network on ``obs``: its head outputs, features and compact rows; the memory moves on.

        What :meth:`act` samples from; a lookahead reads the value and the logits from it
        (:mod:`wfbench.policies.lookahead.search`).
        """
        # a network before the scale-free one computes only the dispatch rows its sampler reads (the choosing
        # facilities): the same bits as the rows of the whole block, which on city is about 30 times larger
        x = scalefree.features(self.model, scalefree.raw_tensors(self.model, obs, self.device), rows_only=True)
        choose = scalefree.compact_rows(self.model, x)
        at = None if choose is None else choose.nonzero(as_tuple=True)
        if at is None:
            out, self._state = self.model(x, self._state, self._starts)
        else:
            out, self._state = self.model(x, self._state, self._starts, at)
        self._starts = torch.zeros_like(self._starts)
        return out, x, choose

    @torch.no_grad()
    def _act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        B, M = obs["requesting"].shape
        N = obs["personnel"].shape[1]
        out, x, choose = self.heads(obs)
        at = None if choose is None else choose.nonzero(as_tuple=True)
        noise = None
        if self.mode != "greedy":
            # greedy-dispatch reads no dispatch noise, but its stream is drawn past all the same
            read = self.mode in ("sample", "greedy-workforce") and "dispatch" in self.decisions
            if not read:
                rows = torch.zeros(B, M, dtype=torch.bool)
            else:  # for a version-1 network the rows read are the choosing facilities
                rows = scalefree.dispatch_rows(self.model, x) if choose is None else choose
            noise = self._noise(B, M, N, rows.cpu().numpy(), None if choose is None else choose.cpu().numpy())
            if self.mode == "greedy-workforce":  # the same stream as sample, the workforce head's noise unread
                noise["workforce"] = torch.zeros_like(noise["workforce"])
        return env_action(scalefree.sample(self.model, out, x, noise, at), M)


def _gumbel(u: np.ndarray) -> np.ndarray:
    """-log(-log(u)) of uniforms, clipped away from 0 and 1 as the trainer's :func:`dist.gumbel` is."""
    return -np.log(-np.log(u.clip(1e-10, 1.0 - 1e-7)))


PPOPolicy = NetworkPolicy  # the name before every algorithm's checkpoints loaded by their own


def from_checkpoint(path: str | Path, mode: str = "sample", device: str = "cpu", name: str | None = None,
                    algo: str | None = None):
    """The deployable policy of a checkpoint: the network alone, or inside a composite with the heuristics.

    ``algo``: the algorithm the caller names (``ALGO:PATH``); a checkpoint of another one is
    refused with a one-line ValueError that says how it loads. None or ``ppo`` (the alias)
    loads any checkpoint. The default name is ``ALGO:PATH`` with the checkpoint's own algorithm.
    """
    ckpt = load_checkpoint(path, device)
    trained_by = checkpoint_algorithm(ckpt)
    if algo is not None and algo not in CHECKPOINT_ALGORITHMS:
        raise ValueError(f"{algo!r} is not a training algorithm; allowed: {', '.join(CHECKPOINT_ALGORITHMS)}")
    if algo not in (None, ALIAS, trained_by):
        allowed = [f"{a}:{path}" for a in dict.fromkeys((trained_by, ALIAS))]
        raise ValueError(f"checkpoint {str(path)!r} was trained by {trained_by}, not {algo}; allowed: "
                         f"{' or '.join(allowed)}")
    model = build_model(ckpt, device)
    name = name or f"{trained_by}:{path}"
    # a run across worlds records them (wfbench.train.worlds): evaluated on one of them, the network is at home
    trained_on = tuple(ckpt["worlds"]) if ckpt.get("worlds") else ckpt.get("scenario")
    net = NetworkPolicy(model, mode=mode, device=device, name=name, trained_on=trained_on)
    net.checkpoint_sha256 = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    if set(net.decisions) == {"dispatch", "workforce", "positioning"}:
        return net
    parts = {d: (net if d in net.decisions else default)
             for d, default in (("dispatch", "nearest"), ("workforce", "threshold"), ("positioning", "spatial"))}
    composite = Composite(**parts, name=name)
    composite.trained_on = net.trained_on
    return composite
