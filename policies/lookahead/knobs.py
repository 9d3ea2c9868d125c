"""The lookaheads' knobs checked one way: the value, or a ValueError of one line naming the knob and what is allowed.

Every lookahead (:mod:`~wfbench.policies.lookahead.rollout`, ``mpc``, ``search``, ``switch``)
takes its knobs through these two checks, with its own name (``kind``) in the message.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def _number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def whole(kind: str, name: str, value: Any, what: str, least: int = 1, allowed: str | None = None) -> int:
    """``value`` as an integer >= ``least`` (a float only where it is a whole number).

    ``what`` says what the knob does; ``allowed`` replaces "an integer >= LEAST" in the message.
    """
    ok = _number(value)
    if ok and isinstance(value, (float, np.floating)):
        ok = math.isfinite(value) and float(value).is_integer()
    if not ok or int(value) < least:
        raise ValueError(f"{kind} knob {name} = {value!r} is not allowed; allowed: "
                         f"{allowed or f'an integer >= {least}'} ({what})")
    return int(value)


def positive(kind: str, name: str, value: Any, what: str, allowed: str = "a number > 0") -> float:
    """``value`` as a float > 0 (not NaN)."""
    if not _number(value) or math.isnan(value) or value <= 0:
        raise ValueError(f"{kind} knob {name} = {value!r} is not allowed; allowed: {allowed} ({what})")
    return float(value)


__all__ = ["positive", "whole"]
