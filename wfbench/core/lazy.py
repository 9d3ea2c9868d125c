"""Names of a package imported on first use (PEP 562), so that importing the package stays cheap.

``wfbench``, ``wfbench.policies`` and ``wfbench.policies.lookahead`` each map some names to
the module that defines them; :func:`names` makes the package's ``__getattr__`` and
``__dir__`` from that map. A name read once is kept on the package, so it is the same
object however often it is read (``wfbench.evaluate`` stays the function even after its
module is imported).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any


def names(package: str, where: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package``: each name of ``where`` imported from its module on first use.

    ``where`` maps a name to ``"module"`` or ``"module:attribute"`` (when the module calls it
    otherwise); a module starting with ``.`` is relative to ``package``.
    """

    def __getattr__(name: str) -> Any:
        found = where.get(name)
        if found is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attr = found.partition(":")
        value = getattr(importlib.import_module(module, package), attr or name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted([*vars(sys.modules[package]), *where])

    return __getattr__, __dir__


__all__ = ["names"]
