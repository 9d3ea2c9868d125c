"""Every metric column of the series, and the episode means, by the formulas of docs/metrics.md.

The differential test compares WC, PUR, AFD and NSW with the reference; the other
columns (the utilities, the headcount and its log) and the running totals behind
``episode_means`` are checked here, from the reference's KPIs and entities.
"""

import math

import numpy as np
import pytest

from wfbench import Simulator
from wfbench.core.state import METRICS

from .reference import EMPTY, ReferenceEnv
from .test_reference_differential import random_actions, random_config


def by_metrics_md(config, wc, pur, afd, head):
    """One row of ``METRICS`` from the KPIs and the headcount (docs/metrics.md)."""
    u_wc = 1.0 - wc / (config.max_personnel * max(config.level_salaries))
    target, tol = config.target_utilization, config.utilization_tolerance
    u_pur = 1.0 - max(0.0, abs(pur - target) - tol) / (max(target, 1.0 - target) - tol)
    u_afd = 1.0 - afd
    nsw = (u_wc * u_pur * u_afd) ** (1.0 / 3.0)
    row = dict(workforce_cost=wc, utilization=pur, downtime=afd, nsw=nsw, u_cost=u_wc, u_utilization=u_pur,
               u_downtime=u_afd, headcount=head, log_headcount=math.log(head) if head > 0 else 0.0)
    return [row[name] for name in METRICS]


@pytest.mark.parametrize("case", range(25))
def test_metrics__every_column_and_the_episode_means_follow_metrics_md(case):
    rng = np.random.default_rng(7000 + case)
    config = random_config(rng).replace(level_salaries=(1.0, 2.5, 4.0))
    sim = Simulator(config, [int(rng.integers(0, 10_000))])
    sim.reset()
    ref = ReferenceEnv(config, sim.trace)
    rows = []
    for t in range(config.horizon):
        d, w, p = random_actions(rng, config.max_facilities, config.max_personnel)
        sim.step({"dispatch": d[None], "workforce": np.array([w]), "positioning": p[None]})
        # ReferenceEnv.step, with the headcount taken when the metrics are (before the next step's departures)
        ref.act(d, w, p)
        ref.advance()
        ref.record()
        head = sum(per.status != EMPTY for per in ref.per)
        ref.t += 1
        if ref.t < config.horizon:
            ref.exogenous()
        wc, pur, afd, _ = ref.metrics[-1]
        rows.append(by_metrics_md(config, wc, pur, afd, head))
        np.testing.assert_allclose(
            sim.state.series[0, t], np.array(rows[-1], dtype=np.float32), rtol=1e-6, atol=1e-7,
            err_msg=f"case {case} step {t}: series columns {METRICS} differ from docs/metrics.md")
    means = sim.episode_means()
    want = np.mean(rows, axis=0)
    for k, name in enumerate(METRICS):
        assert means[name][0] == pytest.approx(want[k], rel=1e-9, abs=1e-12), (
            f"case {case}: episode mean of {name} {means[name][0]} != mean of its per-step values {want[k]}")
