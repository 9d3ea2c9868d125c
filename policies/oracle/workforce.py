"""The workforce oracle's candidates: the seven workforce actions, each with the map it would use.

Every ``every`` steps the oracle scores the no-op, a hire of each level and a let-go
of each level (those the workforce mask allows) by exact roll-forwards of ``horizon``
steps with the workforce frozen afterwards: each candidate is "this headcount for the
next ``horizon`` steps", so a hire is charged its on-boarding delay (``hire_delay``
steps of salary without work) and credited with the work it takes on once on board,
against the failures that will really happen. A hire is scored with each hire site
the positioning oracle proposes (:func:`wfbench.policies.oracle.positioning.hire_sites`),
a let-go with the cheapest person of that level; with positioning left to another
policy, with that policy's map. The best candidate is taken; the no-op wins ties.
Between decision steps the oracle does nothing (a receding horizon: it re-plans at
the next decision step with the world as it then is).
"""

from __future__ import annotations

import numpy as np


def workforce_candidates(mask: np.ndarray, hire_maps: list[np.ndarray], release_maps: list[np.ndarray | None],
                         noop_map: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """The (action, positioning map) candidates of one environment, the no-op first.

    Args:
        mask: (7,) the workforce mask of the observation.
        hire_maps: the distinct maps to score each allowed hire level with.
        release_maps: per level, the map of its let-go (None: that level has nobody to let go).
        noop_map: the map sent with the no-op (unused by the simulator).
    """
    out: list[tuple[int, np.ndarray]] = [(0, noop_map)]
    for lv in range(3):
        if mask[1 + lv]:
            for m in hire_maps:
                out.append((1 + lv, m))
    for lv in range(3):
        if mask[4 + lv] and release_maps[lv] is not None:
            out.append((4 + lv, release_maps[lv]))
    return out
