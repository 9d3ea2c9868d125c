"""A Griffe extension for the API reference: the docstrings' conventions, read as written.

- Some docstrings name other objects the reST way (``:class:`Simulator```,
  ``:func:`~wfbench.core.fork.fork```); Markdown would show the role's name as text.
  Each becomes the code span Sphinx would display: the target, or its last component
  after ``~``, or the title of ``title <target>``.
- A ``Returns:`` or ``Yields:`` section here is prose (the type is the signature's
  annotation), but the Google parser takes whatever stands before a colon on its first
  line as the type ("The outcome: ``complete``, ..."). That colon is written as an
  HTML entity, which the parser does not split on and the page shows as ``:``.

mkdocs.yml loads it (``extensions`` of the mkdocstrings Python handler); the site never
serves this file (``exclude_docs``).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

RETURNS = re.compile(r"\s*(?:Returns|Yields):\s*")
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const|term):`([^`]+)`")


def _shown(target: str) -> str:
    """What Sphinx displays for a role's content."""
    titled = re.fullmatch(r"(.*?)\s*<[^>]+>", target, re.S)
    if titled:
        return titled.group(1)
    if target.startswith("~"):
        return target[1:].rsplit(".", 1)[-1]
    return target


def plain_roles(text: str) -> str:
    """``text`` with every Sphinx role replaced by a Markdown code span."""
    return ROLE.sub(lambda m: f"`{_shown(m.group(1))}`", text)


def prose_returns(text: str) -> str:
    """``text`` with the first colon of each Returns/Yields section kept out of the parser's way."""
    lines = text.split("\n")
    for i, line in enumerate(lines[:-1]):
        if RETURNS.fullmatch(line):
            j = next((k for k in range(i + 1, len(lines)) if lines[k].strip()), None)
            if j is None:
                continue
            first = lines[j]
            colon = next((c for c, ch in enumerate(first) if ch == ":" and first[:c].count("`") % 2 == 0), None)
            if colon is not None:
                lines[j] = first[:colon] + "&#58;" + first[colon + 1:]
    return "\n".join(lines)


class DocstringConventions(griffe.Extension):
    """Rewrites every docstring as it is loaded (see the module docstring)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = prose_returns(plain_roles(obj.docstring.value))
