"""The KPIs in one table: name, label, unit, which direction is better, how each enters the welfare.

Every list of KPIs in wfbench (the simulator's metric columns, the evaluator's frames, the
observation's globals, ``info``, training logs, the leaderboard's columns, every label) reads
:data:`KPIS`; ``tests/contracts/test_kpis.py`` fails when a module writes the list out again.
A new KPI is one row here plus its computation in :func:`wfbench.core.dynamics.record_metrics`,
and a new version by hand of the observation's global features (:mod:`wfbench.core.observe`) and
of the leaderboard store's schema. The score ``nsw`` is the geometric mean of the utilities
(``docs/metrics.md``; ``docs/design.md``, "Metrics, utilities and NSW").
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


# No weight of each utility in the welfare here: the welfare is the cube root of the product of the
# utilities, (u_cost * u_utilization * u_downtime) ** (1/3), computed once in compiled code. Weights read
# from this table could only enter as u_cost ** w * u_utilization ** w * u_downtime ** w, which rounds
# differently: it changes 44% of the per-step welfare values in the last bit (and np.cbrt of the product
# 71%; measured over 2 million random utilities), so every published number would move.
KPIS: tuple[KPI, ...] = (
    KPI("workforce_cost", "Workforce cost", "salary per step (novice 1.0, mid 1.5, expert 2.0)", "lower", "u_cost"),
    KPI("utilization", "Personnel util. rate", "fraction of the rolling window working", "band", "u_utilization"),
    KPI("downtime", "Facility downtime", "fraction of the rolling window down", "lower", "u_downtime"),
    KPI("nsw", "Nash social welfare", "welfare in [0, 1]", "higher", None),
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
"""Columns of the simulator's ``last``, ``totals`` and ``series`` arrays (:mod:`wfbench.core.state`).

``METRICS`` names these per-step columns everywhere; the statistics over seeds and
scenarios (IQM, mean, optimality gap) are :data:`wfbench.analysis.aggregate.STATISTICS`.
"""


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
