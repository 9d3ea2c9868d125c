"""Scenario configuration: a frozen, validated dataclass with named presets.

Every field is checked on construction (a ``ValueError`` naming the field, the value and what is
allowed). Presets (``PRESETS``, from :mod:`wfbench.core.presets`) are looked up with
:meth:`ScenarioConfig.preset`; configs round-trip through TOML and JSON. Names are resolved where
they enter (:mod:`wfbench.scenarios.resolve`); the core takes configs (:func:`require_config`).
Fields in ``OMITTED_AT_DEFAULT`` are written by :meth:`ScenarioConfig.to_dict` only when they
differ from their default, so older scenarios keep their hash. ``docs/model.md`` (the fields),
``docs/scenarios.md``; ``docs/design.md``, "Names resolved where they enter".
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import tomli_w

from wfbench.core.layout import FacilityLayout
from wfbench.core.presets import PRESET_FIELDS
from wfbench.core.schedule import RateSchedule

PLACEMENTS = ("argmax", "sample")
# fields written to dicts and files only when not at their default (see the module docstring)
OMITTED_AT_DEFAULT = ("layout",)


@dataclass(frozen=True)
class ScenarioConfig:
    """Parameters of one simulated world (see ``docs/model.md``)."""

    name: str = "custom"
    grid_width: int = 64
    grid_height: int = 64
    max_facilities: int = 50
    max_personnel: int = 50
    initial_facilities: int = 25
    initial_personnel: int = 25
    min_personnel: int = 1
    horizon: int = 800
    request_interval: float = 40.0
    churn_interval: float = 100.0
    base_fix_rate: float = 0.7
    level_multipliers: tuple[float, float, float] = (0.7, 1.0, 1.2)
    level_probs: tuple[float, float, float] = (0.25, 0.5, 0.25)
    level_salaries: tuple[float, float, float] = (1.0, 1.5, 2.0)
    speed: float = 1.0
    service_time: int = 3
    hire_delay: int = 20
    fire_delay: int = 10
    window: int = 50
    target_utilization: float = 0.75
    utilization_tolerance: float = 0.05
    heat_sigma: float = 6.0
    placement: str = "argmax"
    request_schedule: RateSchedule = field(default_factory=RateSchedule)
    churn_schedule: RateSchedule = field(default_factory=RateSchedule)
    layout: FacilityLayout = field(default_factory=FacilityLayout)

    def __post_init__(self) -> None:
        for name in ("level_multipliers", "level_probs", "level_salaries"):
            value = getattr(self, name)
            try:
                value = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                raise ValueError(f"ScenarioConfig.{name} = {value!r}: allowed: three numbers, one per level") from None
            object.__setattr__(self, name, value)
        for name in ("request_schedule", "churn_schedule"):
            value = getattr(self, name)
            if isinstance(value, dict):
                object.__setattr__(self, name, RateSchedule.from_dict(value))
            elif not isinstance(value, RateSchedule):
                raise ValueError(f"ScenarioConfig.{name} = {value!r}: allowed: a RateSchedule or a dict")
        if isinstance(self.layout, dict):
            object.__setattr__(self, "layout", FacilityLayout.from_dict(self.layout))
        elif not isinstance(self.layout, FacilityLayout):
            raise ValueError(f"ScenarioConfig.layout = {self.layout!r} is not allowed; allowed: a FacilityLayout "
                             "or a dict")
        self._validate()

    # -- validation -------------------------------------------------------------------------
    def _fail(self, name: str, allowed: str) -> None:
        raise ValueError(f"ScenarioConfig.{name} = {getattr(self, name)!r} is not allowed; allowed: {allowed}")

    def _int(self, name: str, lo: int, hi: int | None = None) -> None:
        v = getattr(self, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
            self._fail(name, f"an integer in [{lo}, {hi}]" if hi is not None else f"an integer >= {lo}")

    def _real(self, name: str, lo: float, hi: float | None = None, lo_open: bool = False) -> None:
        v = getattr(self, name)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        ok = ok and (v > lo if lo_open else v >= lo) and (hi is None or v <= hi)
        if not ok:
            low = f"> {lo}" if lo_open else f">= {lo}"
            self._fail(name, f"a finite number {low}" + (f" and <= {hi}" if hi is not None else ""))

    def _validate(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            self._fail("name", "a non-empty string")
        self._int("grid_width", 1, 4096)
        self._int("grid_height", 1, 4096)
        self._int("max_facilities", 1, 4096)
        self._int("max_personnel", 1, 4096)
        self._int("initial_facilities", 0, self.max_facilities)
        self._int("initial_personnel", 0, self.max_personnel)
        self._int("min_personnel", 0, self.initial_personnel)
        self._int("horizon", 1, 1_000_000)
        self._real("request_interval", 0.0, lo_open=True)
        self._real("churn_interval", 0.0, lo_open=True)
        self._real("base_fix_rate", 0.0, 1.0, lo_open=True)
        self._int("service_time", 1, 100_000)
        self._int("hire_delay", 1, 100_000)
        self._int("fire_delay", 0, 100_000)
        self._int("window", 1, 100_000)
        self._real("speed", 0.0, lo_open=True)
        self._real("target_utilization", 0.0, 1.0, lo_open=True)
        self._real("utilization_tolerance", 0.0)
        if self.utilization_tolerance >= max(self.target_utilization, 1.0 - self.target_utilization):
            self._fail("utilization_tolerance", "a number below max(target_utilization, 1 - target_utilization)")
        self._real("heat_sigma", 0.0, lo_open=True)
        if self.placement not in PLACEMENTS:
            self._fail("placement", " or ".join(map(repr, PLACEMENTS)))
        for name in ("level_multipliers", "level_probs", "level_salaries"):
            v = getattr(self, name)
            if len(v) != 3 or not all(math.isfinite(x) and x >= 0 for x in v):
                self._fail(name, "three finite numbers >= 0, one per level (novice, mid, expert)")
        if abs(sum(self.level_probs) - 1.0) > 1e-9:
            self._fail("level_probs", "three probabilities that sum to 1")
        if not all(s > 0 for s in self.level_salaries):
            self._fail("level_salaries", "three salaries > 0")
        if max(self.level_multipliers) * self.base_fix_rate > 1.0 + 1e-12:
            self._fail("level_multipliers",
                       f"multipliers with base_fix_rate * multiplier <= 1 (base_fix_rate={self.base_fix_rate})")
        self.layout.check_grid(self.grid_width, self.grid_height)

    # -- derived -------------------------------------------------------------------------------
    @property
    def fix_probabilities(self) -> tuple[float, float, float]:
        """Probability that one visit by a person of each level fixes the facility."""
        return tuple(self.base_fix_rate * m for m in self.level_multipliers)  # type: ignore[return-value]

    @property
    def max_workforce_cost(self) -> float:
        return self.max_personnel * max(self.level_salaries)

    # -- construction ----------------------------------------------------------------------------
    def replace(self, **changes: Any) -> ScenarioConfig:
        """A copy with some fields changed (validated like any config)."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ValueError(f"unknown ScenarioConfig field(s) {sorted(unknown)}; "
                             f"allowed: {[f.name for f in fields(self)]}")
        return replace(self, **changes)

    @classmethod
    def preset(cls, name: str) -> ScenarioConfig:
        """The named preset; ``ValueError`` listing the presets for an unknown name."""
        if name not in PRESETS:
            raise ValueError(f"unknown scenario {name!r}; available: {', '.join(PRESETS)}")
        return PRESETS[name]

    # -- serialization ---------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The fields as plain data; those of ``OMITTED_AT_DEFAULT`` only when not at their default."""
        d = asdict(self)
        for name in ("level_multipliers", "level_probs", "level_salaries"):
            d[name] = list(d[name])
        d["request_schedule"] = self.request_schedule.to_dict()
        d["churn_schedule"] = self.churn_schedule.to_dict()
        defaults = {f.name: f.default_factory() for f in fields(self) if f.name in OMITTED_AT_DEFAULT}
        for name in OMITTED_AT_DEFAULT:
            d.pop(name)
            if getattr(self, name) != defaults[name]:
                d[name] = getattr(self, name).to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ScenarioConfig:
        allowed = {f.name for f in fields(cls)}
        unknown = set(d) - allowed
        if unknown:
            raise ValueError(f"unknown ScenarioConfig field(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
        return cls(**d)

    def to_toml(self) -> str:
        return tomli_w.dumps(self.to_dict())

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_toml(cls, text: str) -> ScenarioConfig:
        return cls.from_dict(tomllib.loads(text))

    @classmethod
    def from_json(cls, text: str) -> ScenarioConfig:
        return cls.from_dict(json.loads(text))

    def save(self, path: str | Path) -> None:
        path = Path(path)
        if path.suffix == ".toml":
            path.write_text(self.to_toml())
        elif path.suffix == ".json":
            path.write_text(self.to_json())
        else:
            raise ValueError(f"config file {str(path)!r} must end in .toml or .json")

    @classmethod
    def load(cls, path: str | Path) -> ScenarioConfig:
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"config file {str(path)!r} does not exist")
        text = path.read_text()
        try:
            return cls.from_toml(text) if path.suffix == ".toml" else cls.from_json(text)
        except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"config file {str(path)!r} is not valid {path.suffix[1:].upper()}: {exc}") from None


# name -> config; the presets' fields are data in wfbench.core.presets (it imports nothing of the config)
PRESETS: dict[str, ScenarioConfig] = {name: ScenarioConfig(name=name, **f) for name, f in PRESET_FIELDS.items()}


def require_config(value: object, owner: str) -> ScenarioConfig:
    """``value`` when it is a :class:`ScenarioConfig`; the core takes configs, never names.

    Raises:
        TypeError: anything else, in one line naming ``owner`` and the public resolver
            that turns a name into a config where it enters (:func:`wfbench.scenario`).
    """
    if isinstance(value, ScenarioConfig):
        return value
    example = f"wfbench.scenario({value!r})" if isinstance(value, str) else "wfbench.scenario(name)"
    raise TypeError(f"{owner} takes a ScenarioConfig, got {type(value).__name__} {value!r}; "
                    f"resolve a scenario name where it enters, e.g. {example}")
