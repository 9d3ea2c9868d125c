"""Intervals for comparing policies on common seeds.

Both functions use :func:`scipy.stats.bootstrap` (percentile method, 9,999 resamples)
with a fixed random generator, so a table is reproducible to the last digit. Paired
differences resample seeds, not episodes of each policy separately: the policies saw
the same worlds (common random numbers), and pairing removes the between-world
variance from the comparison.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.stats import bootstrap

N_RESAMPLES = 9_999
CONFIDENCE = 0.95


class Interval(NamedTuple):
    estimate: float
    low: float
    high: float

    def format(self, digits: int = 3) -> str:
        return f"{self.estimate:+.{digits}f} [{self.low:+.{digits}f}, {self.high:+.{digits}f}]"

    @property
    def excludes_zero(self) -> bool:
        return self.low > 0.0 or self.high < 0.0


def bootstrap_ci(values: Sequence[float], seed: int = 0) -> Interval:
    """Mean of ``values`` and its bootstrap 95% interval (degenerate when fewer than 2 values)."""
    x = np.asarray(values, dtype=np.float64)
    if x.size == 0:
        raise ValueError("bootstrap_ci needs at least one value")
    mean = float(x.mean())
    if x.size < 2 or np.all(x == x[0]):
        return Interval(mean, mean, mean)
    res = bootstrap((x,), np.mean, n_resamples=N_RESAMPLES, confidence_level=CONFIDENCE, method="percentile",
                    rng=np.random.default_rng(seed))
    return Interval(mean, float(res.confidence_interval.low), float(res.confidence_interval.high))


def paired_difference(a: Sequence[float], b: Sequence[float], seed: int = 0) -> Interval:
    """Mean of ``a - b`` over common seeds (same order) and its bootstrap 95% interval."""
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        raise ValueError(f"paired_difference needs one value per common seed; got {x.shape} and {y.shape}")
    return bootstrap_ci(x - y, seed=seed)
