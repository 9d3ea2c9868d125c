"""The workforce oracle's candidates: the seven workforce actions, each with the map it would use.

Every ``every`` steps the oracle scores the no-op and each hire and let-go the mask allows by
exact roll-forwards of ``horizon`` steps with the workforce frozen afterwards ("this headcount
for the next ``horizon`` steps", on-boarding delay included). A hire is scored with each site
of :func:`wfbench.policies.oracle.positioning.hire_sites`, a let-go with the cheapest person of
its level; the no-op wins ties. A receding horizon: it re-plans at the next decision step
(``docs/hindsight.md``, "Workforce oracle").
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
