"""Facility layouts: where on the grid facilities are, at the start and when they arrive.

A layout (``ScenarioConfig.layout``, :class:`FacilityLayout`) acts only through the trace
(:mod:`wfbench.core.trace`), so it is a pure function of ``(config, seed)`` like every other
exogenous draw. Kinds: ``uniform`` (the default, the paper's), ``clustered`` (``towns`` centres
drawn per seed, normal offsets of ``spread`` cells) and ``sites`` (a fixed weighted list, offsets
of ``jitter`` cells). Cells are rounded and clipped to the grid; personnel homes stay uniform.
The fields, streams and decisions: ``docs/scenarios.md``, "Facility layouts"; the draws:
``docs/model.md``, "Exogenous inputs".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

LAYOUT_KINDS = ("uniform", "clustered", "sites")
# the fields each kind reads besides ``kind``; any other field must keep its default
_KIND_FIELDS = {"uniform": (), "clustered": ("towns", "spread"), "sites": ("sites", "jitter")}


@dataclass(frozen=True)
class FacilityLayout:
    """Where facilities are drawn on the grid; see the module docstring.

    Attributes:
        kind: ``uniform``, ``clustered`` or ``sites``.
        towns: ``clustered``: the number of town centres (>= 1).
        spread: ``clustered``: standard deviation, in cells, of a facility's offset from
            its town centre (> 0).
        sites: ``sites``: ``(x, y, weight)`` triples, x and y in grid cells (real numbers
            are rounded when a facility is placed), weight >= 0 with a positive total.
        jitter: ``sites``: standard deviation, in cells, of a facility's offset from its
            site (>= 0; 0 puts it exactly on the site).
    """

    kind: str = "uniform"
    towns: int = 4
    spread: float = 4.0
    sites: tuple[tuple[float, float, float], ...] = ()
    jitter: float = 0.0

    def __post_init__(self) -> None:
        try:
            sites = tuple(tuple(float(v) for v in s) for s in self.sites)
        except (TypeError, ValueError):
            raise ValueError(f"ScenarioConfig.layout.sites = {self.sites!r} is not allowed; allowed: "
                             "(x, y, weight) triples of numbers") from None
        object.__setattr__(self, "sites", sites)
        if isinstance(self.spread, int) and not isinstance(self.spread, bool):
            object.__setattr__(self, "spread", float(self.spread))
        if isinstance(self.jitter, int) and not isinstance(self.jitter, bool):
            object.__setattr__(self, "jitter", float(self.jitter))
        self._validate()

    def _fail(self, name: str, allowed: str) -> None:
        raise ValueError(f"ScenarioConfig.layout.{name} = {getattr(self, name)!r} is not allowed; allowed: {allowed}")

    def _validate(self) -> None:
        if self.kind not in LAYOUT_KINDS:
            self._fail("kind", ", ".join(map(repr, LAYOUT_KINDS)))
        if isinstance(self.towns, bool) or not isinstance(self.towns, int) or not 1 <= self.towns <= 4096:
            self._fail("towns", "an integer in [1, 4096]")
        if not (isinstance(self.spread, float) and math.isfinite(self.spread) and self.spread > 0):
            self._fail("spread", "a finite number > 0 (cells)")
        if not (isinstance(self.jitter, float) and math.isfinite(self.jitter) and self.jitter >= 0):
            self._fail("jitter", "a finite number >= 0 (cells)")
        for i, s in enumerate(self.sites):
            if len(s) != 3 or not all(math.isfinite(v) for v in s) or s[2] < 0:
                raise ValueError(f"ScenarioConfig.layout.sites[{i}] = {s!r} is not allowed; allowed: "
                                 "(x, y, weight) with finite numbers and weight >= 0")
        if self.kind == "sites" and (not self.sites or sum(s[2] for s in self.sites) <= 0):
            self._fail("sites", "at least one (x, y, weight) site, with weights summing to more than 0")
        for f in fields(self):
            if f.name != "kind" and f.name not in _KIND_FIELDS[self.kind] and getattr(self, f.name) != f.default:
                self._fail(f.name, f"its default {f.default!r}: it applies to the "
                                   f"{' or '.join(k for k, v in _KIND_FIELDS.items() if f.name in v)} layout only, "
                                   f"and this layout is {self.kind!r}")

    def check_grid(self, width: int, height: int) -> None:
        """``ValueError`` naming the first site off a ``width`` x ``height`` grid."""
        for i, (x, y, _) in enumerate(self.sites):
            if not (-0.5 <= x < width - 0.5 and -0.5 <= y < height - 0.5):
                raise ValueError(f"ScenarioConfig.layout.sites[{i}] = {(x, y)!r} is not allowed; allowed: x in "
                                 f"[0, {width - 1}] and y in [0, {height - 1}] (cells of the grid)")

    # -- serialization ---------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """``kind`` and the fields its kind reads (the others are at their defaults)."""
        d: dict[str, Any] = {"kind": self.kind}
        for name in _KIND_FIELDS[self.kind]:
            v = getattr(self, name)
            d[name] = [list(s) for s in v] if name == "sites" else v
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FacilityLayout:
        allowed = {f.name for f in fields(cls)}
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(f"unknown layout field(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
        return cls(**d)

    # -- drawing -----------------------------------------------------------------------------
    def draw(self, width: int, height: int, seed_seq: np.random.SeedSequence, n_initial: int,
             n_arrivals: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cells ``(x0, y0, xa, ya)`` of ``n_initial`` initial and ``n_arrivals`` arriving facilities.

        ``seed_seq`` is the layout's own stream of the seed; it is split into the towns', the
        initial facilities' and the arrivals' streams, so the number of arrivals does not
        move the initial cells. Not for ``uniform`` (the trace draws those itself).
        """
        town_ss, init_ss, arr_ss = seed_seq.spawn(3)
        if self.kind == "clustered":
            rng = np.random.Generator(np.random.PCG64(town_ss))
            mx, my = min(self.spread, (width - 1) / 2), min(self.spread, (height - 1) / 2)
            cx = rng.uniform(mx, width - 1 - mx, size=self.towns)
            cy = rng.uniform(my, height - 1 - my, size=self.towns)
            weights, sd = np.full(self.towns, 1.0 / self.towns), self.spread
        elif self.kind == "sites":
            s = np.asarray(self.sites, dtype=np.float64)
            cx, cy, weights, sd = s[:, 0], s[:, 1], s[:, 2] / s[:, 2].sum(), self.jitter
        else:
            raise ValueError(f"ScenarioConfig.layout.kind = {self.kind!r}: the trace draws uniform cells itself")

        def cells(ss: np.random.SeedSequence, n: int) -> tuple[np.ndarray, np.ndarray]:
            rng = np.random.Generator(np.random.PCG64(ss))
            k = rng.choice(len(weights), size=n, p=weights)
            off = rng.normal(0.0, 1.0, size=(2, n)) * sd
            x = np.clip(np.rint(cx[k] + off[0]), 0, width - 1).astype(np.int64)
            y = np.clip(np.rint(cy[k] + off[1]), 0, height - 1).astype(np.int64)
            return x, y

        return (*cells(init_ss, n_initial), *cells(arr_ss, n_arrivals))


EARTH_RADIUS_KM = 6371.0


def project_latlon(lat, lon, width: int, height: int, margin: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Grid coordinates of points given in degrees: equirectangular, scaled to fit the grid.

    The points are projected equirectangularly about their mean latitude (east-west
    distances shrink by its cosine, so distances are true to within a few percent over a
    region a few hundred kilometres across), then scaled by one factor on both axes so
    the larger extent spans the grid less ``margin`` cells on each side, and centred
    along the other axis. North is towards larger ``y``. A single point (or points that
    coincide) lands in the middle of the grid. Regions across the antimeridian are not
    supported.

    Returns:
        ``(x, y)``: float arrays in ``[margin, width - 1 - margin]`` and
        ``[margin, height - 1 - margin]``.
    """
    lat = np.radians(np.asarray(lat, dtype=np.float64))
    lon = np.radians(np.asarray(lon, dtype=np.float64))
    px = EARTH_RADIUS_KM * lon * math.cos(float(lat.mean()))
    py = EARTH_RADIUS_KM * lat
    margin = min(float(margin), (width - 1) / 2, (height - 1) / 2)
    span_x, span_y = width - 1 - 2 * margin, height - 1 - 2 * margin
    ex, ey = float(px.max() - px.min()), float(py.max() - py.min())
    scales = [s / e for s, e in ((span_x, ex), (span_y, ey)) if e > 0]
    scale = min(scales) if scales else 0.0
    x = margin + (px - px.min()) * scale + (span_x - ex * scale) / 2
    y = margin + (py - py.min()) * scale + (span_y - ey * scale) / 2
    return x, y
