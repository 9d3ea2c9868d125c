"""The stored form of a suite run's pieces: where one lives, its metadata, its rows and its parts.

A piece is one policy on one suite scenario: ``FOLDER/cache/POLICY/SCENARIO.csv`` (one row per
seed, written with every bit) beside a ``.json`` holding the scenario's ``hash``, the ``seeds``
and the ``provenance`` of the run that played them, or a ``parts`` list, one entry per run when
a piece was extended by the seeds it lacked. The suite runner
(:mod:`wfbench.reproduce.pieces`) writes and extends pieces; the replaying oracle
(:mod:`wfbench.policies.oracle.pieces`) reads its candidates' totals from them. Both read
them here, so the format has one reader.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path

import pandas as pd


def piece_folder(policy: str) -> str:
    """The folder of ``policy``'s pieces under ``cache/``: its name made path-safe (``#`` becomes ``_``)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", policy)


def piece_path(out: Path, policy: str, scenario_id: str) -> Path:
    """Where ``policy``'s piece of the suite scenario ``scenario_id`` is stored in the run folder ``out``."""
    return Path(out) / "cache" / piece_folder(policy) / f"{scenario_id}.csv"


def read_meta(path: Path, scenario_hash: str) -> dict | None:
    """The metadata of the piece at ``path`` (its CSV), or None when it or its rows are missing or its hash differs."""
    meta = Path(path).with_suffix(".json")
    if not (Path(path).is_file() and meta.is_file()):
        return None
    m = json.loads(meta.read_text())
    return m if m.get("hash") == scenario_hash else None


def read_rows(path: Path) -> pd.DataFrame:
    """A piece's rows with the same bits as the run that wrote them."""
    return pd.read_csv(path, float_precision="round_trip")


def first_piece(folders: Sequence[Path], policy: str, scenario_id: str,
                seeds: Sequence[int] | None = None) -> pd.DataFrame | None:
    """The rows, by seed, of the first piece of ``policy`` on ``scenario_id`` in the run folders ``folders``.

    The first in ``folders``' order whose rows hold every one of ``seeds`` (any piece when None),
    or None where no folder has one. Neither its ``.json`` nor the scenario's hash is read: for
    scripts over committed runs (``benchmarks/heldout_paired.py``, ``benchmarks/reference_gap.py``),
    not for reuse by a run (:func:`wfbench.reproduce.pieces.find` checks both).
    """
    for folder in folders:
        path = piece_path(folder, policy, scenario_id)
        if path.exists():
            df = read_rows(path).set_index("seed")
            if seeds is None or set(seeds) <= set(df.index):
                return df
    return None


def parts_of(meta: dict) -> list[dict]:
    """The parts of a piece: each ``{"seeds", "wall_s", "provenance"}`` and, where recorded, ``"batches"``.

    One part for a piece played at once.
    """
    if "parts" in meta:
        return meta["parts"]
    part = {"seeds": meta.get("seeds", []), "wall_s": meta.get("wall_s"), "provenance": meta.get("provenance")}
    if "batches" in meta:
        part["batches"] = meta["batches"]
    return [part]


__all__ = ["first_piece", "parts_of", "piece_folder", "piece_path", "read_meta", "read_rows"]
