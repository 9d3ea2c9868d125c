"""What a board's result row is, for the local and the hosted board alike.

The KPI, counter and budget columns of a row, the digest that covers a row's provenance and
values, the columns of the rows the reports rank, and the one-line errors of a board. The local
board (:mod:`wfbench.leaderboard.store`) and the hosted one (:mod:`wfbench.leaderboard.board`)
both store rows of these columns; docs/leaderboard.md#what-a-row-holds.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from pathlib import Path
from typing import Any

from wfbench.core.kpis import KPI_NAMES
from wfbench.harness.budget import BUDGET_COLUMNS

# The KPI columns are the KPI table's names (wfbench.core.kpis), in its order. A new KPI in the table adds a column to
# the rows tables, which needs a migration (and leaves it out of the digest of the rows stored before).
KPI_COLUMNS = KPI_NAMES
ROW_COLUMNS = (*KPI_COLUMNS, "episode_length", "invalid_actions")
# what a row cost (wfbench.harness.budget.BUDGET_COLUMNS, and the machine's line); NULL in rows stored before budgets
BUDGET_ROW_COLUMNS = (*BUDGET_COLUMNS, "machine")


class StoreError(Exception):
    """A board that cannot be used as asked: printed as one line by the CLI."""


class SubmitError(Exception):
    """The submission cannot start (unknown track or policy, name taken, bad limits): one line, exit 2."""


class NameTaken(StoreError):
    """The name is taken on the track by a policy with another fingerprint (or on another track version)."""

    def __init__(self, existing: Any, why: str):
        super().__init__(why)
        self.existing = existing  # the entry that holds the name (a board Submission)
        self.why = why  # "fingerprint" or "track"


def row_digest(name: str, track: str, track_hash: str, policy: str, submitter: str, version: str, seed: int,
               values: dict[str, Any], fingerprint: str = "") -> str:
    """sha256 over a row's provenance, values and budget.

    A legacy row (no fingerprint) keeps the digest it had before fingerprints, a row
    without a budget (no ``machine``) the digest it had before budgets, and a row of a
    one-scenario track (``scenario`` empty) the digest it had before suites.
    """
    payload = [name, track, track_hash, policy, submitter, version, int(seed)]
    payload += [float(values[c]).hex() if c in KPI_COLUMNS else int(values[c]) for c in ROW_COLUMNS]
    if fingerprint:
        payload.append(fingerprint)
    if values.get("machine"):
        payload += [budget_value(values.get(c)) for c in BUDGET_COLUMNS] + [values["machine"]]
    if values.get("scenario"):
        payload += ["scenario", values["scenario"]]
    return hashlib.sha256(json.dumps(payload).encode()).hexdigest()


def budget_value(v: Any) -> str | None:
    """A budget measurement as stored: its exact float, or None for a missing one (SQLite keeps no NaN)."""
    if v is None or not math.isfinite(float(v)):
        return None
    return float(v).hex()


def default_path() -> Path:
    """``$WFBENCH_DB``, else ``wfbench/results.sqlite`` in the user's data folder."""
    env = os.environ.get("WFBENCH_DB")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_data_dir("wfbench", appauthor=False)) / "results.sqlite"


_ABS_PATH = re.compile(r"(?<![\w.~])(?:/|[A-Za-z]:\\)(?:[^\s:'\"()<>,;]*[/\\])?([^\s:'\"()<>,;/\\]+)")


def scrub_paths(text: str, cwd: str | Path | None = None) -> str:
    """``text`` with absolute paths made relative to ``cwd`` when they are under it, else cut to the file name."""
    base = str(Path(cwd).resolve()) + os.sep if cwd is not None else None

    def sub(m: re.Match) -> str:
        path = m.group(0)
        if base and path.startswith(base):
            return path[len(base):]
        return m.group(1)

    return _ABS_PATH.sub(sub, text)


RESULT_FRAME_COLUMNS = ("name", "status", "builtin", "submission_id", "seed", "track", "track_hash", "policy",
                        "submitter", "wfbench_version", "finished_at", *ROW_COLUMNS, "digest", "fingerprint",
                        *BUDGET_ROW_COLUMNS, "scenario")
"""The columns of a board's valid rows as the reports read them (``Store.results``)."""


def check_rows(rows: Any, track: Any) -> tuple[list[dict[str, Any]], list[str]]:
    """The rows of ``track`` a ranking may use, and one message per refused row.

    Each row is a mapping of :data:`RESULT_FRAME_COLUMNS`. A row is refused when its
    track hash is not the track's current one, its seed is not a test seed, its
    scenario is not one of the track's, or its digest does not match its values.
    """
    keep, refused = [], []
    test = set(track.test_seeds)
    units = set(track.units())
    for d in rows:
        where = f"result of {d['name']!r}, {'scenario ' + d['scenario'] + ', ' if d['scenario'] else ''}" \
                f"seed {d['seed']}"
        if d["track_hash"] != track.hash:
            refused.append(f"{where}: made on another version of track {track.name} (hash {d['track_hash']}, "
                           f"current {track.hash}); refused")
            continue
        if d["seed"] not in test:
            refused.append(f"{where}: seed {d['seed']} is not a test seed of track {track.name}; refused")
            continue
        if (d["scenario"], d["seed"]) not in units:
            refused.append(f"{where}: scenario {d['scenario'] or '(none)'!r} is not one of track {track.name}'s; "
                           "refused")
            continue
        expected = row_digest(d["name"], d["track"], d["track_hash"], d["policy"], d["submitter"],
                              d["wfbench_version"], d["seed"], d, d["fingerprint"])
        if expected != d["digest"]:
            refused.append(f"{where}: its values do not match its digest (the row was edited); refused")
            continue
        keep.append(d)
    return keep, refused
