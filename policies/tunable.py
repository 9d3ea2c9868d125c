"""The range of a tunable hyper-parameter: what a tuner may search and a tuned-policy file may set.

Each built-in rule declares the hyper-parameters worth searching, with a :class:`Param`
each (low, high, type, log scale), in its row of :data:`wfbench.policies.rules.RULES`.
``BuiltinDecision.tunable`` and ``Composite.tunable`` read them; a composite names its
parameters ``decision.field`` (``workforce.high``).

The ranges are the allowed values too: a tuned-policy file or a search range outside
them is refused, naming the range.
"""

from __future__ import annotations

import math
from typing import NamedTuple


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
