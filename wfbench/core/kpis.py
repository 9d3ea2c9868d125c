"""The KPIs in one table: name, label, unit, which direction is better, how each enters the welfare.

Every list of KPIs in wfbench (the metric columns of the simulator's arrays, the
evaluator's per-seed columns, the observation's global features, the environments'
``info``, the trainers' episode logs, the leaderboard's store and the reproduced tables)
is read from :data:`KPIS`; ``tests/contracts/test_kpis.py`` fails when a module writes the list out
again. A new KPI is one row here plus its computation in :mod:`wfbench.core.dynamics`.

The welfare (docs/metrics.md): each measured KPI maps to a utility in [0, 1], and the
score ``nsw`` is the geometric mean of the utilities, ``(u_cost * u_utilization *
u_downtime) ** (1/3)``; an episode's score is the mean of the per-step ``nsw``.
"""

from __future__ import annotations

from typing import NamedTuple


class KPI(NamedTuple):
    """One key performance indicator, as every table, frame and log names it."""

    name: str  # the column in per-seed frames, metric arrays and stores
    label: str  # how tables print it
    unit: str  # what one unit of it is
    better: str  # "lower", "higher" or "band" (best inside the target band of utilization)
    utility: str | None  # the utility column through which it enters the welfare (None: the welfare itself)
    welfare_exponent: float  # the exponent of its utility in the welfare (a geometric mean: 1/3 each)


KPIS: tuple[KPI, ...] = (
    KPI("workforce_cost", "Workforce cost", "salary per step (novice 1.0, mid 1.5, expert 2.0)", "lower",
        "u_cost", 1 / 3),
    KPI("utilization", "Personnel util. rate", "fraction of the rolling window working", "band",
        "u_utilization", 1 / 3),
    KPI("downtime", "Facility downtime", "fraction of the rolling window down", "lower", "u_downtime", 1 / 3),
    KPI("nsw", "Nash social welfare", "welfare in [0, 1]", "higher", None, 1.0),
)
"""The three measured KPIs, then the score (the Nash social welfare of their utilities)."""

BY_NAME: dict[str, KPI] = {k.name: k for k in KPIS}
KPI_NAMES: tuple[str, ...] = tuple(k.name for k in KPIS)
"""``("workforce_cost", "utilization", "downtime", "nsw")``: the columns every report shows, in this order."""
MEASURED: tuple[str, ...] = tuple(k.name for k in KPIS if k.utility is not None)
"""The KPIs the welfare is made of (everything but the score)."""
SCORE = "nsw"
"""The KPI everything is ranked by: the episode mean of the per-step welfare."""
UTILITIES: tuple[str, ...] = tuple(k.utility for k in KPIS if k.utility is not None)
KPI_LABELS: dict[str, str] = {k.name: k.label for k in KPIS}

EXTRA_METRICS = ("headcount", "log_headcount")
"""Reported beside the KPIs, not in the welfare: employed people, and the paper's log-headcount cost."""
METRICS: tuple[str, ...] = (*KPI_NAMES, *UTILITIES, *EXTRA_METRICS)
"""Columns of the simulator's ``last``, ``totals`` and ``series`` arrays (:mod:`wfbench.core.state`)."""


def kpi_score(kpi: str, value: float, target_utilization: float = 0.75) -> float:
    """A KPI as a number where higher is better: as it is, negated, or minus its distance to the target."""
    better = BY_NAME[kpi].better if kpi in BY_NAME else None
    if better == "higher":
        return value
    if better == "lower":
        return -value
    if better == "band":
        return -abs(value - target_utilization)
    raise ValueError(f"unknown KPI {kpi!r}; allowed: {', '.join(KPI_NAMES)}")


def better_text(kpi: str, target_utilization: float = 0.75) -> str:
    """Which way is better, in words (``"lower"``, ``"higher"``, ``"closer to the target 0.75"``)."""
    better = BY_NAME[kpi].better
    return f"closer to the target {target_utilization:g}" if better == "band" else better
