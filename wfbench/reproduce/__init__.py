"""Regenerate the paper's Table 2, Table 3 and Figure 3 with wfbench's model, the oracle gap, and the suite.

One module per target (:mod:`~wfbench.reproduce.table2`, :mod:`~wfbench.reproduce.table3`,
:mod:`~wfbench.reproduce.figure3`, :mod:`~wfbench.reproduce.gap`); the paper's numbers are
data (``paper.toml``, read by :mod:`~wfbench.reproduce.paper`). Each target writes markdown
and CSV (and PNG and SVG for the figures) into an output folder and returns the text it
prints. The paper's NSW is a cost (lower is better) and its formulas do not reproduce its
own numbers; ours (``docs/metrics.md``) is a welfare in [0, 1], higher is better. So the
tables put the paper's numbers beside ours and compare orderings and trends, never values;
docs/reproduction.md says what matches and why.
"""

from __future__ import annotations

import wfbench.reproduce.figure3 as figure3
import wfbench.reproduce.gap as gap
import wfbench.reproduce.suite as suite
import wfbench.reproduce.table2 as table2
import wfbench.reproduce.table3 as table3
from wfbench.reproduce.common import Output

TARGETS = {"table2": table2.table2, "table3": table3.table3, "figure3": figure3.figure3, "gap": gap.gap,
           "suite": suite.suite}
"""``wfbench reproduce TARGET``: each called as ``target(out, runs=, backend=, workers=, address=, progress=)``."""

SIZES = {"table2": table2.size, "table3": table3.size, "figure3": figure3.size, "gap": gap.size, "suite": suite.size}


def target_size(name: str, **kwargs) -> int:
    """How many evaluations target ``name`` runs with these keyword arguments (for a progress bar)."""
    return SIZES[name](**kwargs)


__all__ = ["Output", "SIZES", "TARGETS", "target_size"]
