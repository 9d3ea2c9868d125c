"""Your policy through the policy protocol, checked before the evaluator or the leaderboard runs it.

:func:`check_policy` plays a few seeds as one batch, as the evaluator does
(``docs/policies.md``, "The protocol"): ``reset(seeds)``, then ``act(obs)`` at every step,
the decisions the policy does not make taken from the paper's heuristic. At each step it
checks what the evaluator and the simulator ask of an action and that the policy keeps
the masks; then that a second ``reset`` with the same seeds gives the same actions, and
that a seed played alone gets the actions it got in the batch.
The first problem raises a :class:`PolicyCheckError`: one line naming the policy, the
step, the decision and what is allowed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from wfbench.core.actions import AGENTS, ActionError, validate_actions
from wfbench.core.config import ScenarioConfig
from wfbench.core.simulator import Simulator
from wfbench.policies import Policy, get
from wfbench.scenarios.resolve import resolve_scenario

FILLER = "heuristic"  # the decisions a checked policy does not make


class PolicyCheckError(AssertionError):
    """A policy that does not keep the policy protocol; the message is one line."""


def _check_decisions(policy: Any, name: str) -> tuple[str, ...]:
    missing = [m for m in ("decisions", "reset", "act") if not hasattr(policy, m)]
    if missing or not isinstance(policy, Policy):
        raise PolicyCheckError(f"policy {name!r} does not follow the policy protocol: it lacks {', '.join(missing)}; "
                               "a policy has decisions, reset(seeds) and act(obs) (docs/policies.md#the-protocol)")
    decisions = policy.decisions
    if (not isinstance(decisions, tuple) or not decisions or len(set(decisions)) != len(decisions)
            or not set(decisions) <= set(AGENTS)):
        raise PolicyCheckError(f"policy {name!r} has decisions = {decisions!r}; allowed: a tuple of distinct names "
                               f"out of {AGENTS}")
    return decisions


def _check_masks(name: str, t: int, seeds: Sequence[int], obs: dict[str, np.ndarray], decisions: tuple[str, ...],
                 d: np.ndarray, w: np.ndarray, N: int) -> None:
    if "dispatch" in decisions:
        sent = d != N
        allowed = np.take_along_axis(obs["dispatch_mask"], d[..., None], axis=2)[..., 0].astype(bool)
        bad = sent & ~allowed
        if bad.any():
            b, f = (int(i) for i in np.argwhere(bad)[0])
            raise PolicyCheckError(f"policy {name!r} at step {t} sends person {int(d[b, f])} to facility slot {f} in "
                                   f"the environment of seed {seeds[b]}, which dispatch_mask forbids; allowed: a "
                                   f"person p with dispatch_mask[b, f, p] = 1, or {N} (nobody)")
    if "workforce" in decisions:
        bad = ~obs["workforce_mask"][np.arange(len(w)), w].astype(bool)
        if bad.any():
            b = int(np.argwhere(bad)[0][0])
            raise PolicyCheckError(f"policy {name!r} at step {t} chooses workforce action {int(w[b])} in the "
                                   f"environment of seed {seeds[b]}, which workforce_mask forbids; allowed: an action "
                                   "a with workforce_mask[b, a] = 1 (0, the no-op, always is)")


def _play(policy: Any, name: str, decisions: tuple[str, ...], config: ScenarioConfig, seeds: list[int],
          steps: int, masks: bool) -> list[dict[str, np.ndarray]]:
    """The policy's own actions at each step, as the simulator takes them, after checking each."""
    sim = Simulator(config, seeds, keep_series=False)
    filler = get(FILLER) if set(decisions) != set(AGENTS) else None
    obs = sim.reset()
    if getattr(policy, "reads_trace", False):  # a hindsight oracle, handed the scenario as the evaluator does
        policy.attach(sim.config)
    policy.reset(list(seeds))
    if filler is not None:
        filler.reset(list(seeds))
    played = []
    for t in range(steps):
        out = policy.act(obs)
        if not isinstance(out, dict):
            raise PolicyCheckError(f"policy {name!r} at step {t} returned {type(out).__name__} from act; allowed: a "
                                   f"dict with one batched action for each of its decisions {decisions}")
        if set(out) != set(decisions):
            raise PolicyCheckError(f"policy {name!r} at step {t} returned the keys {sorted(out)} from act; allowed: "
                                   f"exactly its decisions {sorted(decisions)}")
        full = {**(filler.act(obs) if filler is not None else {}), **out}
        try:
            d, w, p = validate_actions({a: full[a] for a in AGENTS}, sim.B, sim.M, sim.N)
        except ActionError as exc:
            raise PolicyCheckError(f"policy {name!r} at step {t} returned a malformed action: {exc}") from None
        if masks:
            _check_masks(name, t, seeds, obs, decisions, d, w, sim.N)
        played.append({a: x.copy() for a, x in zip(AGENTS, (d, w, p), strict=True) if a in decisions})
        sim.step({"dispatch": d, "workforce": w, "positioning": p})
        obs = sim.observe()
    return played


def check_policy(policy: Any, scenario: str | ScenarioConfig = "small", seeds: Sequence[int] = (0, 1, 2),
                 steps: int | None = None, masks: bool = True) -> None:
    """Play ``policy`` on ``seeds`` twice and raise :class:`PolicyCheckError` at the first problem.

    Checked, in this order: the protocol (``decisions``, ``reset``, ``act``; ``decisions``
    a tuple of distinct agent names); at every step, that ``act`` returns a dict with
    exactly the policy's decisions, each a well-formed batched action (the shapes, types
    and ranges of ``docs/policies.md#actions``, checked by the simulator's own
    :func:`~wfbench.core.actions.validate_actions`), and, with ``masks``, that no dispatch
    or workforce choice is one its mask forbids; then that a second ``reset(seeds)``
    gives the same actions, bit for bit, at every step, and that the last seed played
    alone gets the actions it got in the batch (a policy's randomness must start over in
    ``reset`` and be keyed by each environment's seed, ``docs/policies.md#batches-and-seeds``).

    Args:
        policy: a policy object, or anything :func:`wfbench.policies.get` takes (a name,
            ``module:attr``).
        scenario: the world to play in (a preset name, a file or a :class:`ScenarioConfig`).
        seeds: the environments of the batch, one seed each.
        steps: steps to play; ``None``, the scenario's whole horizon.
        masks: check that the policy keeps the action masks. A choice a mask forbids is
            legal (the step ignores and counts it), so turn this off for a policy that
            makes such choices on purpose.

    Raises:
        PolicyCheckError: the first problem found, in one line.
        ValueError: ``seeds``, ``steps`` or ``scenario`` is not allowed.
        Exception: what the policy's own ``reset`` or ``act`` raises, as it is (its traceback ends in your code).
    """
    config = resolve_scenario(scenario)
    seeds = [int(s) for s in seeds]
    if not seeds or any(s < 0 for s in seeds):
        raise ValueError(f"seeds={seeds!r} is not allowed; allowed: one or more integers >= 0")
    if steps is None:
        steps = config.horizon
    if not isinstance(steps, int) or not 1 <= steps <= config.horizon:
        raise ValueError(f"steps={steps!r} is not allowed; allowed: 1..{config.horizon} (the horizon), or None")
    if isinstance(policy, str):
        name, policy = policy, get(policy)
    else:
        name = str(getattr(policy, "name", type(policy).__name__))
    decisions = _check_decisions(policy, name)
    first = _play(policy, name, decisions, config, seeds, steps, masks)
    second = _play(policy, name, decisions, config, seeds, steps, masks)
    _compare(name, decisions, seeds, first, second, "when reset with the same seeds again")
    if len(seeds) > 1:  # the last seed alone decides as it did in the batch
        alone = _play(policy, name, decisions, config, seeds[-1:], steps, masks)
        _compare(name, decisions, seeds[-1:], [{a: x[-1:] for a, x in step.items()} for step in first], alone,
                 f"alone and in the batch {seeds}")


def _compare(name: str, decisions: tuple[str, ...], seeds: list[int], first: list[dict[str, np.ndarray]],
             second: list[dict[str, np.ndarray]], when: str) -> None:
    for t, (a, b) in enumerate(zip(first, second, strict=True)):
        for decision in decisions:
            differs = (a[decision] != b[decision]).reshape(len(seeds), -1).any(axis=1)
            if differs.any():
                seed = seeds[int(np.argmax(differs))]
                raise PolicyCheckError(
                    f"policy {name!r} gave different {decision} actions at step {t} in the environment of seed {seed} "
                    f"{when}; allowed: the same actions for the same seed (start the policy's randomness over in "
                    "reset(seeds), keyed by each environment's seed, never by its place in the batch)")
