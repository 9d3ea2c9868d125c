"""Tracks: a named scenario, or a suite of them, with a public (development) seed list and a fixed test seed list.

The ranking uses only the test seeds, which are published too: a result tuned on them says so by
being worthless. A track's definition (the whole scenario config, both seed lists, the
definition's schema version) is hashed; every stored result carries the hash, and results whose
hash differs are refused when read. A :class:`SuiteTrack` (``suite-v1``) runs every scenario of a
suite, has the suite's hash and is ranked by :mod:`wfbench.leaderboard.suite_report`. Both kinds
name what a submission runs as :meth:`Track.units`, (scenario, seed) pairs (scenario ``""`` for
one scenario). ``docs/leaderboard.md``, "Tracks"; ``docs/suite.md``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import PUBLIC, TEST
from wfbench.scenarios import Suite, get_suite

TRACK_SCHEMA = 1


@dataclass(frozen=True)
class Track:
    name: str
    config: ScenarioConfig
    public_seeds: tuple[int, ...]
    test_seeds: tuple[int, ...]
    description: str

    def configs(self) -> dict[str, ScenarioConfig]:
        """The scenarios a submission runs, by the ``scenario`` its rows store: ``""`` for this one."""
        return {"": self.config}

    @property
    def unit_word(self) -> str:
        """What a message calls this track's units."""
        return "seeds"

    def units(self) -> list[tuple[str, int]]:
        """What a complete entry has a row for: (scenario, seed) pairs, in order."""
        return [("", s) for s in self.test_seeds]

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


@dataclass(frozen=True)
class SuiteTrack:
    """A track over every scenario of a suite: one row per (scenario id, test seed), hashed with the suite's hash.

    Ranked by the IQM of the normalized score over the held-out scenarios (shown for the
    training scenarios too), with its 95% stratified bootstrap interval
    (:func:`wfbench.analysis.aggregate.aggregate_suite`); a learned method's training seeds, each an
    entry, are ranked together by the pool of their runs (:func:`wfbench.analysis.aggregate.pool_seeds`).
    """

    name: str
    suite: Suite
    description: str

    @property
    def public_seeds(self) -> tuple[int, ...]:
        return self.suite.public_seeds

    @property
    def test_seeds(self) -> tuple[int, ...]:
        return self.suite.test_seeds

    @property
    def hash(self) -> str:
        """The suite's hash (:attr:`wfbench.scenarios.Suite.hash`): its scenarios, splits, versions and seeds."""
        return self.suite.hash

    def configs(self) -> dict[str, ScenarioConfig]:
        return {sc.id: sc.config for sc in self.suite.scenarios}

    @property
    def unit_word(self) -> str:
        """What a message calls this track's units."""
        return "(scenario, seed) episodes"

    def units(self) -> list[tuple[str, int]]:
        return [(sc.id, s) for sc in self.suite.scenarios for s in self.test_seeds]


def suite_track(suite: str | Suite, description: str | None = None) -> SuiteTrack:
    """The track of a suite (a name such as ``"suite-v1"`` or a :class:`~wfbench.scenarios.Suite`), named after it."""
    s = get_suite(suite)
    return SuiteTrack(name=s.name, suite=s, description=description or (
        f"every scenario of suite {s.name} ({len(s.ids('train'))} training, {len(s.ids('heldout'))} held out)"))


def _track(name: str, description: str, preset: str | None = None) -> Track:
    return Track(
        name=name,
        config=ScenarioConfig.preset(preset or name),
        public_seeds=tuple(PUBLIC),  # the named seed sets of wfbench.core.seeds
        test_seeds=tuple(TEST),
        description=description,
    )


TRACKS: dict[str, Track | SuiteTrack] = {
    t.name: t
    for t in (
        _track("paper-64", "the paper's quantitative comparison: 64x64, <= 50 facilities and 50 people, "
                           "about 25 of each at start, 800 steps"),
        _track("nonstationary", "paper-64 with request and churn rates drifting over the episode"),
        _track("large", "256x256, 200 facility and 200 personnel slots, 100 of each at start"),
        suite_track("suite-v1"),
    )
}


def get_track(name: str) -> Track | SuiteTrack:
    if name not in TRACKS:
        raise ValueError(f"unknown track {name!r}; available: {', '.join(TRACKS)}")
    return TRACKS[name]
