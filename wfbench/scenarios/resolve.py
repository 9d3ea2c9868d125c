"""Scenario names: one grammar, resolved once where a name enters wfbench.

Every command and function that takes a scenario takes the same names, resolved here and nowhere
else: :func:`resolve_scenario` (``wfbench.scenario``) takes a :class:`ScenarioConfig`, a ``.toml``
or ``.json`` path, a preset name or a suite's versioned id (``paper-64-v1``);
:func:`resolve_worlds` (what ``--scenarios`` takes) comma-separated scenarios, suite ids and
splits (``suite-v1:train``), naming a suite's scenario by its suite id. What is inward of the
edge is handed the config and refuses a name. The grammar: ``docs/scenarios.md``, "Naming a
scenario"; why: ``docs/design.md``, "Names resolved where they enter".
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from wfbench.core.config import PRESETS, ScenarioConfig
from wfbench.scenarios.suites import SPLITS, SUITES, SuiteScenario

FILE_SUFFIXES = (".toml", ".json")
SEPARATOR = ","  # between the items of a spec of several worlds
ALLOWED = ("a preset name ('wfbench scenarios' lists them), a suite's scenario id such as paper-64-v1 "
           "('wfbench suite show suite-v1' lists them) or a .toml/.json file")


@dataclass(frozen=True)
class World:
    """One world of a spec of several: the name logs and checkpoints use, its scenario, and its suite and split.

    ``suite`` and ``split`` are those of the suite that holds the scenario (``None`` for a
    scenario no suite holds, such as a user's file).
    """

    name: str
    config: ScenarioConfig
    suite: str | None = None
    split: str | None = None


def _suite_scenario(name: str, *, presets: bool) -> tuple[str, SuiteScenario] | None:
    """The first suite (in definition order) that holds ``name`` as an id (or, with ``presets``, as a preset)."""
    for suite_name, suite in SUITES.items():
        for sc in suite.scenarios:
            if sc.id == name or (presets and sc.preset == name):
                return suite_name, sc
    return None


def resolve_scenario(spec: str | os.PathLike | ScenarioConfig) -> ScenarioConfig:
    """The scenario of a name, a file or a config (the module docstring has the grammar).

    Raises:
        ValueError: a name that is none of these, or a file that is missing or malformed;
            one line naming what is allowed.
        TypeError: ``spec`` is neither a string, a path nor a :class:`ScenarioConfig`.
    """
    if isinstance(spec, ScenarioConfig):
        return spec
    if isinstance(spec, os.PathLike):
        return ScenarioConfig.load(Path(spec))
    if not isinstance(spec, str):
        raise TypeError(f"scenario must be {ALLOWED.replace(' or a ', ', a ')} or a ScenarioConfig, "
                        f"got {type(spec).__name__}")
    if spec.endswith(FILE_SUFFIXES):
        return ScenarioConfig.load(spec)
    if spec in PRESETS:
        return ScenarioConfig.preset(spec)
    found = _suite_scenario(spec, presets=False)
    if found is not None:
        return found[1].config
    raise ValueError(f"unknown scenario {spec!r}; available: {', '.join(PRESETS)} (presets), a suite's scenario id "
                     "such as paper-64-v1 ('wfbench suite show suite-v1' lists them) or a .toml/.json file")


def resolve_worlds(spec: str, *, heldout: bool = True) -> list[World]:
    """The worlds of a spec of several (the module docstring has the grammar), in its order, each once.

    Args:
        spec: comma-separated scenarios, suite ids and ``SUITE:SPLIT`` items.
        heldout: whether a suite's held-out scenarios are allowed; training and tuning
            pass ``False``, and a held-out scenario, split or whole suite is refused.

    Raises:
        ValueError: an empty item, an unknown suite split or scenario, a held-out one
            where they are refused; one line naming what is allowed.
    """
    items = [s.strip() for s in spec.split(SEPARATOR)] if isinstance(spec, str) else []
    if not items or not all(items):
        raise ValueError(f"scenarios {spec!r}: allowed: a comma-separated list of scenarios and suite splits, "
                         "e.g. 'suite-v1:train' or 'paper-64,small'")
    worlds: dict[str, World] = {}

    def add(suite: str, sc: SuiteScenario) -> None:
        worlds.setdefault(sc.id, World(sc.id, sc.config, suite, sc.split))

    for item in items:
        suite, colon, split = item.partition(":")
        if suite in SUITES:
            splits = SPLITS if heldout else ("train",)
            allowed = ", ".join(f"{suite}:{s}" for s in splits) + (f" or {suite}" if heldout else "")
            if colon and split not in SPLITS:
                raise ValueError(f"scenarios {item!r}: unknown split {split!r} of {suite}; allowed: {allowed}")
            if (split if colon else "heldout") not in splits:
                what = f"the {split} split is" if colon else "its held-out scenarios are"
                raise ValueError(f"scenarios {item!r}: {what} never trained on; allowed: {allowed}")
            for sid in SUITES[suite].ids(split if colon else None):
                add(suite, SUITES[suite].scenario(sid))
            continue
        found = None if item.endswith(FILE_SUFFIXES) else _suite_scenario(item, presets=True)
        if found is None:
            config = resolve_scenario(item)
            worlds.setdefault(config.name, World(config.name, config))
            continue
        suite, sc = found
        if sc.split != "train" and not heldout:
            raise ValueError(f"scenarios {item!r}: {sc.id} is a held-out scenario of {suite} and is never trained "
                             f"on; allowed: its training split, {suite}:train")
        add(suite, sc)
    return list(worlds.values())
