"""The rewards of a step, defined once: the environments and the trainers read them from here.

``"nsw"`` is the step's ``NSW_t`` (:mod:`wfbench.core.kpis`), the number an episode's score
averages, and what every agent of the PettingZoo environment gets; ``"nsw-no-cost"`` is the
paper's dispatch-only reward, ``sqrt(u_utilization * u_downtime)`` (a dispatcher cannot change
the headcount). A trainer's shaping sits on top (:mod:`wfbench.train.collection`;
``docs/design.md``, "Metrics, utilities and NSW").
"""

from __future__ import annotations

import numpy as np

from wfbench.core.state import K_UAFD, K_UPUR

REWARDS = {
    "nsw": "the step's Nash social welfare, the leaderboard's score",
    "nsw-no-cost": "the welfare without the workforce-cost term, sqrt(u_utilization * u_downtime): the paper's "
                   "dispatch-only reward",
}


def check_reward(kind: str) -> str:
    """``kind`` if it names a reward, else a ValueError that lists the rewards."""
    if kind not in REWARDS:
        raise ValueError(f"reward {kind!r} is not allowed; allowed: {', '.join(REWARDS)}")
    return kind


def step_reward(kind: str, nsw: np.ndarray, last: np.ndarray) -> np.ndarray:
    """The reward of each environment for the step just taken.

    Args:
        kind: a key of :data:`REWARDS`.
        nsw: (B,) float64, the step's welfare (what ``Simulator.step`` returns).
        last: (B, len(METRICS)) float64, the step's metrics (``Simulator.state.last``).

    Returns:
        (B,) float64; for ``"nsw"``, ``nsw`` itself (not a copy).
    """
    if kind == "nsw":
        return nsw
    if kind == "nsw-no-cost":
        return np.sqrt(np.clip(last[:, K_UPUR] * last[:, K_UAFD], 0.0, None))
    raise ValueError(f"reward {kind!r} is not allowed; allowed: {', '.join(REWARDS)}")
