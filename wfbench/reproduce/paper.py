"""The paper's numbers (``paper.toml`` beside this module), as the reproduction targets use them."""

from __future__ import annotations

import tomllib
from functools import cache
from pathlib import Path
from typing import NamedTuple

PAPER_FILE = Path(__file__).resolve().with_name("paper.toml")


class PaperRow(NamedTuple):
    """One row of the paper's Table 3: its number, the policy of each decision, its KPIs as printed."""

    row: str
    parts: tuple[str, str, str]  # dispatch, workforce, positioning
    kpis: tuple[str, ...]  # WC, PUR, AFD, NSW (a cost), each "mean (q25-q75)"

    @property
    def text(self) -> str:
        return " / ".join(self.kpis)


@cache
def _read() -> dict:
    with PAPER_FILE.open("rb") as f:
        return tomllib.load(f)


def table2_nsw_cost() -> dict[int, tuple[float, ...]]:
    """Table 2: the paper's NSW (a cost, lower is better) by grid, one value per cell of ``TABLE2_CELLS``."""
    return {int(grid): tuple(float(v) for v in values) for grid, values in _read()["table2"]["nsw_cost"].items()}


def table3_rows() -> list[PaperRow]:
    """Table 3 rows 1-7 as the paper prints them."""
    return [PaperRow(r["row"], tuple(r["parts"]), tuple(r["kpis"])) for r in _read()["table3"]]
