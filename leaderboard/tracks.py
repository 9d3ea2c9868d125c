"""Tracks: a suite of scenarios (one for ``paper-64``, sixteen for ``suite-v1``) with public and test seeds.

Every track is a :class:`Track` and is ranked by one rule (:func:`wfbench.leaderboard.report.ranking`).
The ranking uses only the test seeds, which are published too: a result tuned on them says so by
being worthless. A track's definition is hashed; every stored result carries the hash, and results
whose hash differs are refused when read. A track of one scenario keeps the definition, so the hash,
and the row key (scenario ``""``) it had before suites. ``docs/leaderboard.md``, "Tracks".
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import PUBLIC, TEST
from wfbench.scenarios import Suite, SuiteScenario, get_suite, normalize
from wfbench.scenarios.score import scale

TRACK_SCHEMA = 1
REFERENCE_SUITE = "suite-v1"  # the suite whose published constants normalize a one-scenario track of its scenarios


@dataclass(frozen=True)
class Track:
    """A named suite of scenarios with its seed lists: what a submission runs and what the board ranks.

    Attributes:
        name: the track's name.
        suite: its scenarios (with their splits) and seed lists; the published normalization
            constants of ``suite.name`` apply to its scenarios (:func:`wfbench.scenarios.normalize`).
        description: one line.
        references: ``(scenario id, random_ref, bound_ref)`` for scenarios without published constants.
        seeded: whether ``wfbench leaderboard baselines`` fills it when no track is named (a long track is not).
    """

    name: str
    suite: Suite
    description: str
    references: tuple[tuple[str, float, float], ...] = ()
    seeded: bool = True

    @property
    def public_seeds(self) -> tuple[int, ...]:
        return self.suite.public_seeds

    @property
    def test_seeds(self) -> tuple[int, ...]:
        return self.suite.test_seeds

    @property
    def config(self) -> ScenarioConfig:
        """The config of its first scenario (of its only one, on a one-scenario track)."""
        return self.suite.scenarios[0].config

    def scenarios(self) -> list[tuple[str, SuiteScenario]]:
        """(the ``scenario`` its rows store, the scenario) in order: ``""`` on a track of one scenario."""
        one = len(self.suite.scenarios) == 1
        return [("" if one else sc.id, sc) for sc in self.suite.scenarios]

    def configs(self) -> dict[str, ScenarioConfig]:
        """The scenarios a submission runs, by the ``scenario`` its rows store."""
        return {key: sc.config for key, sc in self.scenarios()}

    @property
    def unit_word(self) -> str:
        """What a message calls this track's units."""
        return "seeds" if len(self.suite.scenarios) == 1 else "(scenario, seed) episodes"

    def units(self) -> list[tuple[str, int]]:
        """What a complete entry has a row for: (scenario, seed) pairs, in order."""
        return [(key, s) for key in self.configs() for s in self.test_seeds]

    @property
    def rank_split(self) -> str:
        """The split the board ranks by: ``heldout`` where the track has held-out scenarios, else ``all``."""
        return "heldout" if any(sc.split == "heldout" for sc in self.suite.scenarios) else "all"

    def normalized(self, key: str, nsw: Any) -> np.ndarray:
        """The normalized score (0 = the random policy, 1 = the proven bound) of NSW values on one scenario.

        Raises:
            ValueError: no constants for the scenario (none given, none published for its definition).
        """
        sc = dict(self.scenarios())[key]
        given = {r[0]: r[1:] for r in self.references}
        if sc.id not in given:
            return np.asarray(normalize(np.asarray(nsw, dtype=float), sc.id, self.suite), dtype=float)
        return scale(nsw, *given[sc.id])

    def definition(self) -> dict[str, Any]:
        """What the hash covers: the suite's definition, or (one scenario) the definition it had before suites."""
        if len(self.suite.scenarios) > 1:
            return self.suite.definition()
        return {"schema": TRACK_SCHEMA, "name": self.name, "scenario": self.config.to_dict(),
                "public_seeds": list(self.public_seeds), "test_seeds": list(self.test_seeds)}

    @property
    def hash(self) -> str:
        """sha256 of the canonical JSON of the definition (first 16 hex digits); a suite's is the suite's hash."""
        text = json.dumps(self.definition(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_seeds(self, test_seeds: tuple[int, ...], description: str) -> Track:
        """This track ranked on other test seeds (a hosted phase's), described as ``description``."""
        return dataclasses.replace(self, suite=dataclasses.replace(self.suite, test_seeds=tuple(test_seeds)),
                                   description=description)


def scenario_track(name: str, config: ScenarioConfig, public_seeds: tuple[int, ...], test_seeds: tuple[int, ...],
                   description: str, references: Mapping[str, tuple[float, float]] | None = None) -> Track:
    """A track of one scenario: a suite of one.

    A config that is one of :data:`REFERENCE_SUITE`'s scenarios is that scenario (its id, split and
    published constants); any other is a training scenario named after ``config.name``, normalized
    with ``references`` (scenario id -> (random_ref, bound_ref)) where given, else left unranked.
    """
    ref = get_suite(REFERENCE_SUITE)
    mine = json.dumps(config.to_dict(), sort_keys=True)
    found = [sc for sc in ref.scenarios if json.dumps(sc.config.to_dict(), sort_keys=True) == mine]
    if found:
        suite = dataclasses.replace(ref, scenarios=(found[0],), public_seeds=tuple(public_seeds),
                                    test_seeds=tuple(test_seeds))
    else:
        sc = SuiteScenario(id=config.name or name, preset=config.name or name, version=1, split="train",
                           why=description, config=config)
        suite = Suite(name=name, version=1, scenarios=(sc,), description=description,
                      public_seeds=tuple(public_seeds), test_seeds=tuple(test_seeds))
    given = tuple((k, float(lo), float(hi)) for k, (lo, hi) in (references or {}).items())
    return Track(name, suite, description, given)


def suite_track(suite: str | Suite, description: str | None = None) -> Track:
    """The track of a suite (a name such as ``"suite-v1"`` or a :class:`~wfbench.scenarios.Suite`), named after it.

    It runs every scenario of the suite, so ``wfbench leaderboard baselines`` fills it only when named.
    """
    s = get_suite(suite)
    return Track(name=s.name, suite=s, seeded=False, description=description or (
        f"every scenario of suite {s.name} ({len(s.ids('train'))} training, {len(s.ids('heldout'))} held out)"))


def _track(name: str, description: str) -> Track:
    return scenario_track(name, ScenarioConfig.preset(name), tuple(PUBLIC), tuple(TEST), description)


TRACKS: dict[str, Track] = {
    t.name: t
    for t in (
        _track("paper-64", "the paper's quantitative comparison: 64x64, <= 50 facilities and 50 people, "
                           "about 25 of each at start, 800 steps"),
        _track("nonstationary", "paper-64 with request and churn rates drifting over the episode"),
        _track("large", "256x256, 200 facility and 200 personnel slots, 100 of each at start"),
        suite_track("suite-v1"),
    )
}


def get_track(name: str) -> Track:
    if name not in TRACKS:
        raise ValueError(f"unknown track {name!r}; available: {', '.join(TRACKS)}")
    return TRACKS[name]
