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


def score_public(policy: Callable[[str], Any], scenario, eval_seeds: str) -> dict:
    """Mean NSW and workforce cost on the public selection seeds, sampled and greedy (the score is the sampled one).

    ``policy(mode)`` gives the deployable policy in ``mode`` (``"sample"`` or ``"greedy"``).
    """
    seeds = resolve_seeds(eval_seeds)
    if isinstance(scenario, WorldSet):
        return score_worlds(policy, scenario, seeds)
    res: dict = {}
    for mode in ("sample", "greedy"):
        df = evaluate(policy(mode), scenario, seeds, backend="serial", act_timeout_s=None)
        res[mode] = float(df["nsw"].mean())
        res[f"{mode}_workforce_cost"] = float(df["workforce_cost"].mean())
    res["seeds"] = seeds
    return res


def score_worlds(policy: Callable[[str], Any], worlds: WorldSet, seeds: list[int]) -> dict:
    """A run across worlds: the sampled policy on the public seeds of every world; the score is their mean.

    Each world's mean NSW is put on the suite's normalized scale (``(NSW - random) /
    (bound - random)``, :func:`wfbench.scenarios.normalize`, the published constants of the
    world's suite id) when every world has constants, so that no world counts more because
    its NSW spreads more; otherwise the score is the mean NSW over the worlds. The
    constants are fixed numbers per scenario: no test-seed result of the policy enters.
    Greedy decisions are not scored (one mode, to halve the cost of scoring eight worlds).
    """
    nsw, cost = {}, {}
    for w in worlds.worlds:
        df = evaluate(policy("sample"), w.config, seeds, backend="serial", act_timeout_s=None)
        nsw[w.name], cost[w.name] = float(df["nsw"].mean()), float(df["workforce_cost"].mean())
    try:
        per_world = {name: float(normalize(v, name)) for name, v in nsw.items()}
        scale = "normalized"
    except ValueError:  # a world no suite has constants for: the plain mean NSW
        per_world, scale = dict(nsw), "nsw"
    return {"sample": float(np.mean(list(per_world.values()))), "greedy": None, "scale": scale,
            "worlds": per_world, "nsw_worlds": nsw,
            "sample_workforce_cost": float(np.mean(list(cost.values()))), "seeds": seeds}


def log_public(writer, res: dict, step: int) -> None:
    """The TensorBoard scalars of a :func:`score_public` result (``public/*``; across worlds, one per world too)."""
    writer.add_scalar("public/nsw_sample" if res.get("scale", "nsw") == "nsw" else "public/score_sample",
                      res["sample"], step)
    if res["greedy"] is not None:
        writer.add_scalar("public/nsw_greedy", res["greedy"], step)
    writer.add_scalar("public/workforce_cost_sample", res["sample_workforce_cost"], step)
    for name, v in res.get("worlds", {}).items():
        writer.add_scalar(f"public/{name}", v, step)
