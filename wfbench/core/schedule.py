"""Rate schedules: how an exogenous rate changes over an episode.

A :class:`RateSchedule` maps each step ``t`` to a positive multiplier ``m(t)`` of a base rate
(the failure rate ``1 / request_interval`` or the arrival rate ``1 / churn_interval``):
``constant`` (1), ``piecewise`` (``values[i]`` from ``times[i]`` on, ``times[0] = 0``),
``seasonal`` (``1 + amplitude * sin(2 pi (t / period + phase))``, ``0 <= amplitude < 1``) or
``drift`` (linear from ``start`` at ``t = 0`` to ``end`` at ``t = horizon``); ``docs/scenarios.md``,
"The fields".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

KINDS = ("constant", "piecewise", "seasonal", "drift")


@dataclass(frozen=True)
class RateSchedule:
    """A multiplier of a base rate over time; see the module docstring."""

    kind: str = "constant"
    times: tuple[int, ...] = field(default=())
    values: tuple[float, ...] = field(default=())
    amplitude: float = 0.0
    period: float = 200.0
    phase: float = 0.0
    start: float = 1.0
    end: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "times", tuple(int(x) for x in self.times))
        object.__setattr__(self, "values", tuple(float(x) for x in self.values))
        if self.kind not in KINDS:
            raise ValueError(f"schedule kind {self.kind!r} is not allowed; allowed: {', '.join(KINDS)}")
        if self.kind == "piecewise":
            if len(self.times) == 0 or len(self.times) != len(self.values):
                raise ValueError(
                    "piecewise schedule needs times and values of equal, non-zero length, "
                    f"got {len(self.times)} times and {len(self.values)} values"
                )
            if self.times[0] != 0 or any(b <= a for a, b in zip(self.times, self.times[1:], strict=False)):
                raise ValueError(f"piecewise schedule times must start at 0 and increase, got {self.times}")
            if any(not (math.isfinite(v) and v > 0) for v in self.values):
                raise ValueError(f"piecewise schedule values must be finite and > 0, got {self.values}")
        if self.kind == "seasonal":
            if not (0.0 <= self.amplitude < 1.0):
                raise ValueError(f"seasonal schedule amplitude must be in [0, 1), got {self.amplitude}")
            if not (math.isfinite(self.period) and self.period > 0):
                raise ValueError(f"seasonal schedule period must be > 0, got {self.period}")
        if self.kind == "drift":
            for name in ("start", "end"):
                v = getattr(self, name)
                if not (math.isfinite(v) and v > 0):
                    raise ValueError(f"drift schedule {name} must be finite and > 0, got {v}")

    def multipliers(self, horizon: int) -> np.ndarray:
        """Multiplier for every step ``0..horizon`` as a float64 array of length ``horizon + 1``."""
        t = np.arange(horizon + 1, dtype=np.float64)
        if self.kind == "constant":
            return np.ones(horizon + 1)
        if self.kind == "piecewise":
            idx = np.searchsorted(np.asarray(self.times), t, side="right") - 1
            return np.asarray(self.values, dtype=np.float64)[idx]
        if self.kind == "seasonal":
            return 1.0 + self.amplitude * np.sin(2.0 * np.pi * (t / self.period + self.phase))
        return self.start + (self.end - self.start) * t / max(horizon, 1)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["times"] = list(self.times)
        d["values"] = list(self.values)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> RateSchedule:
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"unknown schedule field(s) {sorted(unknown)}; "
                             f"allowed: {sorted(cls.__dataclass_fields__)}")
        return cls(**d)
