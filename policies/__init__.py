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

from wfbench.core.lazy import names as _names

# name -> the module that defines it, imported when the name is first read (PEP 562): importing a kernel imports this
# package, and the registry behind ``get`` imports every family, which would then be in every kernel's closure
_LAZY = {"BuiltinDecision": ".builtin", "Composite": ".composite", "DECISIONS": ".decisions", "Policy": ".protocol",
         "get": ".registry", "names": ".registry"}
__getattr__, __dir__ = _names(__name__, _LAZY)

__all__ = ["BuiltinDecision", "Composite", "DECISIONS", "Policy", "get", "names"]
