"""The policy a trainer's network makes, and its score on the public seeds that selects checkpoints.

Checkpoints are selected on the public seeds only (:func:`score_public`); across worlds,
on the suite's normalized score (:func:`score_worlds`). ``docs/rl.md``, "Generalists".
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from wfbench import policies
from wfbench.core.seeds import resolve_seeds
from wfbench.harness.evaluation import evaluate
from wfbench.policies.neural.policy import NetworkPolicy
from wfbench.scenarios.score import normalize
from wfbench.train.worlds import WorldSet


def deployable(model: torch.nn.Module, variant: str, mode: str = "sample", name: str = "ppo"):
    """The policy the network makes: alone (joint) or with the heuristic workforce and positioning (dispatch)."""
    net = NetworkPolicy(copy.deepcopy(model).float().cpu(), mode=mode, device="cpu", name=name)
    if variant == "joint":
        return net
    return policies.Composite(net, "threshold", "spatial", name=name)


SELECT_MODES = ("sample", "greedy")


def score_public(policy: Callable[[str], Any], scenario, eval_seeds: str, select: str = "sample") -> dict:
    """Mean NSW and workforce cost on the public selection seeds, sampled and greedy; ``select`` names the score.

    ``policy(mode)`` gives the deployable policy in ``mode`` (``"sample"`` or ``"greedy"``).
    The result's ``select`` is the mode whose score picks ``best.pt``
    (:meth:`wfbench.train.outputs.RunOutputs.public`): the sampled one, or the greedy one for
    a trainer whose network is deployed greedy (distillation).
    """
    seeds = resolve_seeds(eval_seeds)
    if isinstance(scenario, WorldSet):
        return score_worlds(policy, scenario, seeds, select)
    res: dict = {}
    for mode in SELECT_MODES:
        df = evaluate(policy(mode), scenario, seeds, act_timeout_s=None)
        res[mode] = float(df["nsw"].mean())
        res[f"{mode}_workforce_cost"] = float(df["workforce_cost"].mean())
    res["seeds"] = seeds
    res["select"] = select
    return res


def score_worlds(policy: Callable[[str], Any], worlds: WorldSet, seeds: list[int], mode: str = "sample") -> dict:
    """A run across worlds: the policy in ``mode`` on the public seeds of every world; the score is their mean.

    Each world's mean NSW is put on the suite's normalized scale (``(NSW - random) /
    (bound - random)``, :func:`wfbench.scenarios.normalize`, the published constants of the
    world's suite id) when every world has constants, so that no world counts more because
    its NSW spreads more; otherwise the score is the mean NSW over the worlds. The
    constants are fixed numbers per scenario: no test-seed result of the policy enters.
    One mode only, ``"sample"`` unless asked (to halve the cost of scoring eight worlds): the
    other mode's score is None.
    """
    nsw, cost = {}, {}
    for w in worlds.worlds:
        df = evaluate(policy(mode), w.config, seeds, act_timeout_s=None)
        nsw[w.name], cost[w.name] = float(df["nsw"].mean()), float(df["workforce_cost"].mean())
    try:
        per_world = {name: float(normalize(v, name)) for name, v in nsw.items()}
        scale = "normalized"
    except ValueError:  # a world no suite has constants for: the plain mean NSW
        per_world, scale = dict(nsw), "nsw"
    score = float(np.mean(list(per_world.values())))
    return {**{m: score if m == mode else None for m in SELECT_MODES}, "scale": scale, "worlds": per_world,
            "nsw_worlds": nsw, f"{mode}_workforce_cost": float(np.mean(list(cost.values()))), "seeds": seeds,
            "select": mode}


def log_public(writer, res: dict, step: int) -> None:
    """The TensorBoard scalars of a :func:`score_public` result (``public/*``; across worlds, one per world too)."""
    across = res.get("scale", "nsw") != "nsw"
    for mode in SELECT_MODES:
        if res.get(mode) is not None:
            writer.add_scalar(f"public/{'score' if across else 'nsw'}_{mode}", res[mode], step)
        if res.get(f"{mode}_workforce_cost") is not None:
            writer.add_scalar(f"public/workforce_cost_{mode}", res[f"{mode}_workforce_cost"], step)
    for name, v in res.get("worlds", {}).items():
        writer.add_scalar(f"public/{name}", v, step)
