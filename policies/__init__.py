"""Everything that decides: random, heuristics, solver-backed decisions and composites.

Modules, bottom up (each imports only those before it): ``table`` (the one table of
registered policies, a typed entry each, which every family fills with its own),
``kernels`` (compiled decision rules), ``protocol`` (the policy protocol and shared
helpers), ``builtin`` (one decision by a kernel), ``solver`` (solver-backed decisions),
``decisions`` (the per-decision table), ``composite``, ``registry`` (names and entry
points, read from ``table``), ``rollout`` (whole episodes compiled); ``tunable``
declares each kernel's tunable parameters and ranges, ``tuned`` reads and writes
tuned-policy files (``wfbench tune``). ``docs/design.md`` draws the layers;
``docs/policies.md`` is the protocol for your own policy.
"""

import importlib

_LAZY = {"BuiltinDecision": "builtin", "Composite": "composite", "DECISIONS": "decisions", "Policy": "protocol",
         "get": "registry", "names": "registry"}


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


__all__ = ["BuiltinDecision", "Composite", "DECISIONS", "Policy", "get", "names"]
