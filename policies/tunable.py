"""What each built-in kernel lets a tuner change: its hyper-parameters with their ranges.

A kernel reads its row of the hyper-parameter matrix (:data:`wfbench.policies.kernels.HP_FIELDS`)
at run time, so a tuned value reaches the compiled rollout without a recompile. This
module declares, per decision kernel, the fields worth searching and the range of each
(:class:`Param`: low, high, type, log scale). ``BuiltinDecision.tunable`` and
``Composite.tunable`` read it; a composite names its parameters ``decision.field``
(``workforce.high``). The model-of-the-world fields (``speed``, ``service_time``,
``fix_*``) are not declared: they are the scenario's facts, not choices.

The ranges are the allowed values too: a tuned-policy file or a search range outside
them is refused, naming the range.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from wfbench.policies import kernels as K


class Param(NamedTuple):
    """One tunable hyper-parameter: ``low <= value <= high``, ``type`` ``"float"`` or ``"int"``, ``log`` scale."""

    low: float
    high: float
    type: str = "float"
    log: bool = False

    def describe(self) -> str:
        return f"{self.type} in [{self.low:g}, {self.high:g}]{' (log scale)' if self.log else ''}"

    def check(self, value: float, name: str) -> float | int:
        """``value`` as this parameter's type, or ValueError naming the range."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"parameter {name} = {value!r} is not a number; allowed: {self.describe()}")
        if self.type == "int":
            if float(value) != int(value):
                raise ValueError(f"parameter {name} = {value!r} is not a whole number; allowed: {self.describe()}")
            value = int(value)
        if not self.low <= value <= self.high:
            raise ValueError(f"parameter {name} = {value!r} is out of range; allowed: {self.describe()}")
        return value if self.type == "int" else float(value)

    def narrowed(self, low: float, high: float, name: str) -> Param:
        """This parameter searched over [low, high] only, which must lie inside its declared range."""
        for v in (low, high):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"range of {name}: {v!r} is not a number; allowed: within {self.describe()}")
        if not low < high:
            raise ValueError(f"range of {name}: low {low:g} must be below high {high:g}")
        if low < self.low or high > self.high:
            raise ValueError(f"range of {name}: [{low:g}, {high:g}] is not allowed; allowed: within "
                             f"{self.describe()}")
        if self.type == "int" and (low != int(low) or high != int(high)):
            raise ValueError(f"range of {name}: [{low:g}, {high:g}] must be whole numbers ({self.describe()})")
        return self._replace(low=low, high=high)


# the threshold rule's parameters, shared by both threshold kernels
_LEVELS = {
    "p_novice": Param(0.0, 1.0),  # relative weights of the level a hire gets (and a let-go takes)
    "p_mid": Param(0.0, 1.0),
    "p_expert": Param(0.0, 1.0),
}
_THRESHOLD = {
    "high": Param(0.3, 1.0),  # hire when utilization is above this
    "low": Param(0.0, 0.9),  # let go when below this
    "cooldown": Param(1, 100, "int"),
    "warmup": Param(0, 200, "int"),
    **_LEVELS,
}
_SPATIAL = {
    "smoothing": Param(0.001, 0.5, log=True),
    "request_weight": Param(0.0, 1.0),
}

# (decision, kernel code) -> field -> range
KERNEL_PARAMS: dict[tuple[str, int], dict[str, Param]] = {
    ("dispatch", K.D_ASSIGN): {
        "revisit_cost": Param(0.0, 50.0),
    },
    ("workforce", K.W_THRESHOLD): _THRESHOLD,
    ("workforce", K.W_EPSILON): {**_THRESHOLD, "epsilon": Param(0.0, 0.5)},
    ("workforce", K.W_STAFFING): {
        "beta": Param(-1.0, 3.0),
        "hysteresis": Param(0.0, 6.0),
        "rate_smoothing": Param(0.001, 0.5, log=True),
        "cooldown": Param(1, 100, "int"),
        "warmup": Param(0, 200, "int"),
        **_LEVELS,
    },
    ("positioning", K.P_SPATIAL): _SPATIAL,
    ("positioning", K.P_GAUSSIAN): {**_SPATIAL, "noise": Param(0.0, 2.0)},
    ("positioning", K.P_FACILITY): {
        "refresh": Param(1, 100, "int"),
        "demand_floor": Param(0.0, 5.0),
        **_SPATIAL,
    },
}


def kernel_params(decision: str, code: int) -> dict[str, Param]:
    """The tunable fields of the kernel ``code`` for ``decision`` (empty: nothing to tune)."""
    return dict(KERNEL_PARAMS.get((decision, int(code)), {}))
