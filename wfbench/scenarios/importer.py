"""A scenario from a user's own files: their sites, and optionally a log of their service requests.

``from_files(sites, requests, name=..., base="paper-64")`` returns a
:class:`~wfbench.core.config.ScenarioConfig`; ``wfbench scenario import`` writes it as TOML or
JSON. The sites (``id``; ``x``, ``y`` or ``lat``, ``lon``; ``weight``) become a ``sites`` layout;
the request log (``time``, ``site``) is fitted to rates, not replayed: site weights, the
``request_interval`` and a ``piecewise`` request schedule. A malformed file raises
:class:`ScenarioFileError` naming the file, line, column, value and what is allowed. The formats:
``docs/scenarios.md``, "Your own sites and requests".
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.layout import FacilityLayout, project_latlon
from wfbench.core.schedule import RateSchedule
from wfbench.scenarios.resolve import resolve_scenario

MARGIN = 2.0  # cells kept free on each side when lat/lon sites are projected
MAX_BINS = 48  # pieces of a fitted request schedule at most
REQUESTS_PER_BIN = 20  # and at least this many requests per piece on average
QUIET_FLOOR = 0.02  # a time bin without requests gets this fraction of the mean rate (a rate must be > 0)
SITES_FORMAT = "a header naming id, x and y (grid cells) or lat and lon (degrees), and weight (optional)"
REQUESTS_FORMAT = "a header naming time (a step or an ISO 8601 timestamp) and site (an id of the sites file)"


class ScenarioFileError(ValueError):
    """A malformed sites or requests file; the message names the file, line, column and what is allowed."""

    def __init__(self, path: str | Path, line: int | None, problem: str, allowed: str, column: str | None = None):
        where = str(path) + (f", line {line}" if line else "") + (f", column {column!r}" if column else "")
        super().__init__(f"{where}: {problem}; allowed: {allowed}")
        self.path, self.line, self.column = str(path), line, column


@dataclass(frozen=True)
class Site:
    id: str
    x: float
    y: float
    weight: float


def _read(path: str | Path, what: str, required_any: str) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header and the non-blank rows (with their line numbers) of a CSV file."""
    p = Path(path)
    if not p.is_file():
        raise ScenarioFileError(path, None, f"the {what} file does not exist", "a path to a CSV file")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        line = p.read_bytes()[: exc.start].count(b"\n") + 1
        raise ScenarioFileError(path, line, "the text is not UTF-8", "a UTF-8 CSV file") from None
    reader = csv.reader(text.splitlines())
    header: list[str] | None = None
    rows: list[tuple[int, list[str]]] = []
    try:
        for fields_ in reader:
            if not fields_ or all(not f.strip() for f in fields_):
                continue
            if header is None:
                header = [f.strip().lower() for f in fields_]
                continue
            rows.append((reader.line_num, [f.strip() for f in fields_]))
    except csv.Error as exc:
        raise ScenarioFileError(path, reader.line_num, f"not valid CSV ({exc})", "a CSV file") from None
    if header is None:
        raise ScenarioFileError(path, 1, "the file is empty", required_any)
    for i, name in enumerate(header):
        if name in header[:i]:
            raise ScenarioFileError(path, 1, f"column {name!r} appears twice in the header", required_any)
    for line, row in rows:
        if len(row) != len(header):
            raise ScenarioFileError(path, line, f"{len(row)} fields", f"{len(header)} fields, one per column "
                                    f"of the header ({', '.join(header)})")
    if not rows:
        raise ScenarioFileError(path, 2, "no data after the header", f"one line per {what[:-1]} after the header")
    return header, rows


def _number(path, line: int, column: str, text: str, lo: float, hi: float, allowed: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ScenarioFileError(path, line, f"{text!r} is not allowed", allowed, column)
    return v


def read_sites(path: str | Path, width: int, height: int) -> list[Site]:
    """The sites of a sites file, on a ``width`` x ``height`` grid (lat/lon are projected onto it)."""
    header, rows = _read(path, "sites", SITES_FORMAT)
    has_xy = "x" in header or "y" in header
    has_ll = "lat" in header or "lon" in header
    if "id" not in header:
        raise ScenarioFileError(path, 1, "no column 'id' in the header", SITES_FORMAT)
    if has_xy and has_ll:
        raise ScenarioFileError(path, 1, "both x, y and lat, lon in the header", f"one pair: {SITES_FORMAT}")
    pair = ("x", "y") if has_xy else ("lat", "lon")
    for name in pair:
        if name not in header:
            raise ScenarioFileError(path, 1, f"no column {name!r} in the header", SITES_FORMAT)
    col = {name: header.index(name) for name in header}
    limits = {"x": (0, width - 1, f"a grid column in [0, {width - 1}]"),
              "y": (0, height - 1, f"a grid row in [0, {height - 1}]"),
              "lat": (-90, 90, "a latitude in degrees, in [-90, 90]"),
              "lon": (-180, 180, "a longitude in degrees, in [-180, 180]")}
    ids: dict[str, int] = {}
    a, b, weights = [], [], []
    for line, row in rows:
        sid = row[col["id"]]
        if not sid:
            raise ScenarioFileError(path, line, "an empty id", "a non-empty id, unique in the file", "id")
        if sid in ids:
            raise ScenarioFileError(path, line, f"id {sid!r} is already on line {ids[sid]}", "unique ids", "id")
        ids[sid] = line
        a.append(_number(path, line, pair[0], row[col[pair[0]]], *limits[pair[0]]))
        b.append(_number(path, line, pair[1], row[col[pair[1]]], *limits[pair[1]]))
        w = row[col["weight"]] if "weight" in col else ""
        weights.append(1.0 if w == "" else _number(path, line, "weight", w, 0, math.inf, "a finite number >= 0"))
    if sum(weights) <= 0:
        raise ScenarioFileError(path, rows[0][0], "every weight is 0", "at least one weight > 0", "weight")
    x, y = (np.asarray(a), np.asarray(b)) if has_xy else project_latlon(a, b, width, height, MARGIN)
    return [Site(sid, round(float(sx), 3), round(float(sy), 3), w)
            for sid, sx, sy, w in zip(ids, x, y, weights, strict=True)]


def read_requests(path: str | Path, site_ids: Sequence[str], horizon: int) -> tuple[list[str], np.ndarray, bool]:
    """The site and the time of each request of a request log.

    Returns:
        ``(sites, times, stamped)``: the site id of each request, its time (a step, or
        seconds since the epoch for timestamps) and whether the times were timestamps.
    """
    header, rows = _read(path, "requests", REQUESTS_FORMAT)
    for name in ("time", "site"):
        if name not in header:
            raise ScenarioFileError(path, 1, f"no column {name!r} in the header", REQUESTS_FORMAT)
    ti, si = header.index("time"), header.index("site")
    known = set(site_ids)
    shown = ", ".join(list(site_ids)[:5]) + (", ..." if len(site_ids) > 5 else "")
    sites, times = [], []
    stamped: bool | None = None
    aware: bool | None = None
    for line, row in rows:
        text, sid = row[ti], row[si]
        if sid not in known:
            raise ScenarioFileError(path, line, f"site {sid!r} is not in the sites file",
                                    f"an id of the sites file ({shown})", "site")
        is_step = text.isdigit()
        if stamped is None:
            stamped = not is_step
        if is_step and not stamped:
            step = int(text)
            if step >= horizon:
                raise ScenarioFileError(path, line, f"step {step} is past the episode",
                                        f"a step in [0, {horizon - 1}] (the base scenario's horizon)", "time")
            times.append(float(step))
        else:
            try:
                stamp = datetime.fromisoformat(text)
            except ValueError:
                stamp = None
            if stamp is None or not stamped:
                first = "steps" if not stamped else "ISO 8601 timestamps"
                raise ScenarioFileError(path, line, f"{text!r} is not allowed",
                                        f"{first} on every line, like the first (a step is an integer >= 0, a "
                                        "timestamp like 2024-03-01T08:30:00)", "time")
            if aware is None:
                aware = stamp.tzinfo is not None
            if aware != (stamp.tzinfo is not None):
                raise ScenarioFileError(path, line, f"{text!r} is not allowed",
                                        "timestamps all with a time zone or all without, like the first", "time")
            times.append((stamp if aware else stamp.replace(tzinfo=UTC)).timestamp())
        sites.append(sid)
    t = np.asarray(times)
    if stamped and t.max() == t.min():
        raise ScenarioFileError(path, rows[-1][0], "every request has the same time",
                                "timestamps spanning some time (the span becomes one episode)", "time")
    return sites, t, bool(stamped)


def fit_schedule(times: np.ndarray, start: float, end: float, horizon: int) -> RateSchedule:
    """A piecewise request schedule of the requests' time profile over ``[start, end]``, mapped onto the horizon.

    The span is cut into equal bins (at most ``MAX_BINS``, about ``REQUESTS_PER_BIN``
    requests each on average); a bin's multiplier is its count over the mean count, a
    bin without requests gets ``QUIET_FLOOR``, and the multipliers are scaled back to
    mean 1 so the schedule moves requests in time without changing their number.
    """
    bins = int(min(MAX_BINS, len(times) // REQUESTS_PER_BIN, horizon))
    if bins <= 1:
        return RateSchedule()
    counts, _ = np.histogram(times, bins=bins, range=(start, end))
    mult = np.maximum(counts / counts.mean(), QUIET_FLOOR)
    mult = mult / mult.mean()
    steps = tuple(round(k * horizon / bins) for k in range(bins))
    return RateSchedule(kind="piecewise", times=steps, values=tuple(float(round(m, 6)) for m in mult))


def from_files(sites: str | Path, requests: str | Path | None = None, *, name: str,
               base: str | ScenarioConfig = "paper-64", jitter: float = 0.0) -> ScenarioConfig:
    """The scenario of a sites file and, optionally, a request log (see the module docstring).

    Args:
        sites: the sites CSV file.
        requests: the request log CSV file, or ``None`` to keep the base's rates and the
            sites' own weights.
        name: the new scenario's name.
        base: the scenario everything else comes from (a preset name, a file or a config).
        jitter: the ``sites`` layout's jitter in cells.

    Raises:
        ScenarioFileError: a malformed file (naming the file, line and column).
        ValueError: a bad ``name``, ``base`` or ``jitter``.
    """
    cfg = resolve_scenario(base)
    found = read_sites(sites, cfg.grid_width, cfg.grid_height)
    weights = {s.id: s.weight for s in found}
    changes: dict = {"name": name}
    if requests is not None:
        site_of, times, stamped = read_requests(requests, [s.id for s in found], cfg.horizon)
        counts = dict.fromkeys(weights, 0.0)
        for sid in site_of:
            counts[sid] += 1.0
        weights = counts
        start, end = (float(times.min()), float(times.max())) if stamped else (0.0, float(cfg.horizon))
        changes["request_schedule"] = fit_schedule(times, start, end, cfg.horizon)
        # F facilities each failing every request_interval steps give F * horizon / request_interval requests
        changes["request_interval"] = max(cfg.initial_facilities, 1) * cfg.horizon / len(times)
    layout = FacilityLayout(kind="sites", sites=tuple((s.x, s.y, weights[s.id]) for s in found), jitter=jitter)
    return cfg.replace(layout=layout, **changes)
