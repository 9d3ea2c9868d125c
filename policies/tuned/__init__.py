"""Tuned-policy files: a base policy and the hyper-parameters a search chose for it.

``wfbench tune`` writes one (JSON, or TOML by the file's suffix); ``policies.get`` reads one
wherever a policy is named: ``path/to/file.json``, ``tuned:path/to/file.json`` or a registered
name (``heuristic-tuned``, a file under ``policies/tuned/``). ``base`` is a built-in composite
name or a ``D+W+P`` composite; ``params`` are its ``Composite.tunable`` names with values in
range; the file also records how it was made (scenario, seeds, trials, command). A file whose
seeds include test seeds is refused. The format: ``docs/policies.md``, "Tuning".
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from wfbench.policies.table import SINCE_V1, SINCE_V2, Entry, TunedFile, register

from wfbench.core.paths import TUNED as TUNED_PACKAGE
from wfbench.core.paths import data_path
from wfbench.core.seeds import TEST

FORMAT = "wfbench-tuned-policy"
FORMAT_VERSION = 1
SUFFIXES = (".json", ".toml")
PREFIX = "tuned:"
TUNED_DIR = data_path(TUNED_PACKAGE)  # this package's folder, policies/tuned/: the shipped files beside this code
REQUIRED = ("base", "params", "scenario", "seeds", "trials", "best_score")


@dataclass(frozen=True)
class TunedPolicy:
    """The contents of a tuned-policy file."""

    name: str
    base: str
    params: dict[str, float | int]
    scenario: str
    seeds: list[int]
    trials: int
    best_score: float
    objective: str = "mean nsw"
    seed_set: str = ""
    wfbench_version: str = ""
    command: str = ""
    study_name: str = ""
    sampler_seed: int = 0
    extra: dict[str, Any] = field(default_factory=dict)  # anything else the file holds, kept as it is

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        extra = d.pop("extra")
        return {"format": FORMAT, "format_version": FORMAT_VERSION, **d, **extra}


def is_tuned_spec(spec: str) -> bool:
    """True for ``tuned:PATH`` and for a path ending in .json or .toml."""
    return spec.startswith(PREFIX) or spec.lower().endswith(SUFFIXES)


def spec_path(spec: str) -> Path:
    return Path(spec[len(PREFIX):] if spec.startswith(PREFIX) else spec)


def _fail(path: Path, what: str) -> ValueError:
    return ValueError(f"tuned-policy file {str(path)!r}: {what}")


def read(path: str | Path) -> TunedPolicy:
    """Read and check a tuned-policy file (JSON, or TOML by suffix).

    Raises:
        ValueError: the file is missing, unreadable, not a tuned-policy file, lacks a
            field, or was tuned on test seeds; the message names the file and the field.
    """
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise _fail(path, f"unknown suffix {path.suffix!r}; allowed: {', '.join(SUFFIXES)}")
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise _fail(path, "no such file") from None
    except OSError as exc:
        raise _fail(path, f"cannot read it: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise _fail(path, f"not valid {path.suffix[1:].upper()}: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise _fail(path, f"not a tuned-policy file (it needs \"format\": {FORMAT!r}, as 'wfbench tune' writes)")
    if data.get("format_version") != FORMAT_VERSION:
        raise _fail(path, f"format_version {data.get('format_version')!r} is not supported; allowed: "
                    f"{FORMAT_VERSION}")
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise _fail(path, f"missing field(s) {', '.join(missing)}")
    if not isinstance(data["base"], str) or not data["base"] or is_tuned_spec(data["base"]):
        raise _fail(path, f"base {data['base']!r} must be a registry name or a D+W+P composite, not a file")
    params = data["params"]
    if not isinstance(params, dict) or not all(isinstance(k, str) for k in params):
        raise _fail(path, "params must be a table of parameter name -> number")
    seeds = data["seeds"]
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and not isinstance(s, bool)
                                                           for s in seeds):
        raise _fail(path, "seeds must be the non-empty list of seeds the search scored on")
    on_test = sorted(set(seeds) & set(TEST))
    if on_test:
        raise _fail(path, f"it was tuned on test seeds ({on_test[0]}..{on_test[-1]}); a policy tuned on the "
                    "seeds that are reported makes the report worthless: tune on public seeds (--seeds public)")
    score = data["best_score"]
    if isinstance(score, bool) or not isinstance(score, (int, float)) or not math.isfinite(score):
        raise _fail(path, f"best_score {score!r} is not a number")
    known = {f for f in TunedPolicy.__dataclass_fields__ if f != "extra"}
    extra = {k: v for k, v in data.items() if k not in known and k not in ("format", "format_version")}
    return TunedPolicy(
        name=str(data.get("name") or path.stem), base=data["base"], params=dict(params),
        scenario=str(data["scenario"]), seeds=list(seeds), trials=int(data["trials"]), best_score=float(score),
        objective=str(data.get("objective", "mean nsw")), seed_set=str(data.get("seed_set", "")),
        wfbench_version=str(data.get("wfbench_version", "")), command=str(data.get("command", "")),
        study_name=str(data.get("study_name", "")), sampler_seed=int(data.get("sampler_seed", 0)), extra=extra,
    )


def write(tuned: TunedPolicy, path: str | Path) -> Path:
    """Write ``tuned`` as JSON (or TOML for a .toml path)."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"tuned-policy file {str(path)!r}: allowed suffixes: {', '.join(SUFFIXES)}")
    data = tuned.to_dict()
    if path.suffix.lower() == ".toml":
        import tomli_w

        text = tomli_w.dumps(data)
    else:  # indented, with the seed list on one line so that the file stays small to read
        seeds = data.pop("seeds")
        text = json.dumps(data, indent=2).replace('\n  "trials"', f'\n  "seeds": {json.dumps(seeds)},\n  "trials"', 1)
        text += "\n"
    path.write_text(text)
    return path


def build(tuned: TunedPolicy, base: Any, path: str | Path | None = None) -> Any:
    """The base policy with the tuned parameters; ValueError names a parameter the base does not have."""
    if not hasattr(base, "with_params"):
        raise ValueError(f"tuned-policy file {str(path)!r}: its base {tuned.base!r} has no tunable parameters")
    try:
        policy = base.with_params(tuned.params, name=tuned.name)
    except ValueError as exc:
        raise ValueError(f"tuned-policy file {str(path)!r}: {exc}") from None
    policy.tuned_from = tuned  # how it was made, for reports
    return policy


# the tuned-policy files shipped with wfbench, by name (docs/policies.md, "Tuning"; wfbench.policies.table):
# the two tuned on paper-64 are candidates of every oracle, those tuned on suite-v1's training split came after v1
register(
    Entry("heuristic-tuned", "tuned", TunedFile("heuristic-paper-64.json"),
          "the heuristic composite tuned on paper-64's public seeds (wfbench tune)",
          candidate_of=SINCE_V1),
    Entry("solver-tuned", "tuned", TunedFile("solver-paper-64.json"),
          "the solver composite tuned jointly on paper-64's public seeds (wfbench tune)",
          candidate_of=SINCE_V1),
    Entry("heuristic-tuned-train", "tuned", TunedFile("heuristic-suite-v1-train.json"),
          "the heuristic composite tuned on suite-v1's training split: the mean normalized score over its eight "
          "scenarios' public seeds (wfbench tune --scenarios suite-v1:train)",
          candidate_of=SINCE_V2),
    Entry("solver-tuned-train", "tuned", TunedFile("solver-suite-v1-train.json"),
          "the solver composite tuned jointly on suite-v1's training split: the mean normalized score over its eight "
          "scenarios' public seeds (wfbench tune --scenarios suite-v1:train)",
          candidate_of=SINCE_V2),
)
