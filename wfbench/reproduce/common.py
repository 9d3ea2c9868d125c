"""What the reproduction targets share: their result, how they write a table, the note on direction."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from wfbench.harness.backends import Execution

DIRECTION = ("Direction: our NSW is a welfare in [0, 1] (docs/metrics.md), higher is better; the paper's NSW "
             "column is a cost, lower is better. Compare orderings and trends, not values.")

Progress = Callable[[str], None] | None
"""Called with the name of each evaluation as it starts (a progress bar's step)."""

PROCESS = Execution(backend="process")
"""The targets' default execution: a pool of processes over all cores (numbers do not depend on it)."""


@dataclass
class Output:
    """What a target wrote: the text it prints and the files."""

    text: str
    files: list[Path]


def checkout_root() -> Path | None:
    """The folder holding the committed results (``docs/results``): the checkout wfbench runs from, or None."""
    from wfbench.core.paths import package_dir

    root = package_dir("wfbench").parent
    return root if (root / "docs" / "results").is_dir() else None


def write(out: Path, stem: str, md: str, df: pd.DataFrame) -> list[Path]:
    """Write ``stem.md`` (the markdown) and ``stem.csv`` (the frame) into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    md_path, csv_path = out / f"{stem}.md", out / f"{stem}.csv"
    md_path.write_text(md + "\n")
    df.to_csv(csv_path, index=False)
    return [md_path, csv_path]
