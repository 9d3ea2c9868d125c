"""Tracks: a named scenario with a public (development) seed list and a fixed test seed list.

The ranking uses only the test seeds. Tune on the public seeds; the test seeds are
published too (this is a benchmark, not a competition with a hidden set), but a
result that was tuned on them says so by being worthless. A track's definition (the
whole scenario config, both seed lists and the schema version of the definition) is
hashed; every stored result carries the hash, and results whose hash differs from the
current definition are refused when read.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import PUBLIC, TEST

TRACK_SCHEMA = 1


@dataclass(frozen=True)
class Track:
    name: str
    config: ScenarioConfig
    public_seeds: tuple[int, ...]
    test_seeds: tuple[int, ...]
    description: str

    def definition(self) -> dict[str, Any]:
        return {
            "schema": TRACK_SCHEMA,
            "name": self.name,
            "scenario": self.config.to_dict(),
            "public_seeds": list(self.public_seeds),
            "test_seeds": list(self.test_seeds),
        }

    @property
    def hash(self) -> str:
        """sha256 of the canonical JSON of the definition (first 16 hex digits)."""
        text = json.dumps(self.definition(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _track(name: str, description: str, preset: str | None = None) -> Track:
    return Track(
        name=name,
        config=ScenarioConfig.preset(preset or name),
        public_seeds=tuple(PUBLIC),  # the named seed sets of wfbench.core.seeds
        test_seeds=tuple(TEST),
        description=description,
    )


TRACKS: dict[str, Track] = {
    t.name: t
    for t in (
        _track("paper-64", "the paper's quantitative comparison: 64x64, <= 50 facilities and 50 people, "
                           "about 25 of each at start, 800 steps"),
        _track("nonstationary", "paper-64 with request and churn rates drifting over the episode"),
        _track("large", "256x256, 200 facility and 200 personnel slots, 100 of each at start"),
    )
}


def get_track(name: str) -> Track:
    if name not in TRACKS:
        raise ValueError(f"unknown track {name!r}; available: {', '.join(TRACKS)}")
    return TRACKS[name]
