"""Tune a policy's declared hyper-parameters on public seeds with Optuna's TPE.

``tune("heuristic", "paper-64", trials=100)`` searches the parameters the policy declares
(``Composite.tunable``) for the highest mean NSW over the tuning seeds and writes a tuned-policy
file (:mod:`wfbench.policies.tuned`); ``scenarios="suite-v1:train"`` maximizes the mean normalized
score over training worlds instead. Test seeds are refused. The study lives in SQLite, so a
repeated call runs only the missing trials, and a differing call is refused. Deterministic: a
seeded sampler, deterministic evaluations, the untuned policy as the first trial. ``wfbench tune``
is its command line; ``docs/policies.md``, "Tuning".
"""

from __future__ import annotations

import math
import re
import shlex
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import optuna
from tqdm.auto import tqdm

from wfbench import __version__
from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import PUBLIC, TEST, TRAIN_START, describe, resolve_seeds
from wfbench.harness.backends import Execution, check_execution
from wfbench.harness.evaluation import evaluate
from wfbench.policies import get
from wfbench.policies import tuned as tuned_file
from wfbench.policies.tunable import Param
from wfbench.scenarios import SUITES, normalize
from wfbench.scenarios.resolve import resolve_scenario
from wfbench.train.worlds import WorldSet, world_set

DEFAULT_DB = "wfbench-tune.db"
OBJECTIVE = "mean nsw"
OBJECTIVE_WORLDS = "mean normalized score"  # across worlds: the mean over the worlds of each one's normalized score


@dataclass(frozen=True)
class TuneResult:
    """What a :func:`tune` call did and found."""

    tuned: tuned_file.TunedPolicy  # the file's contents
    path: Path | None  # where it was written
    study_name: str
    study_db: Path
    new_trials: int  # finished by this call
    untuned_score: float | None  # the base policy's score on the tuning seeds (the study's first trial)


def check_tuning_seeds(seeds: int | str | Iterable[int]) -> list[int]:
    """The seed list, if it is allowed for tuning (public or train seeds), else ValueError saying why."""
    seed_list = resolve_seeds(seeds)
    on_test = sorted(set(seed_list) & set(TEST))
    if on_test:
        raise ValueError(f"seeds {on_test[0]}..{on_test[-1]} are test seeds: tuning on the seeds that are reported "
                         "makes the reported numbers worthless; allowed: public seeds (--seeds public, 1000-1049, "
                         "or public:N) or train seeds (train:N)")
    other = [s for s in seed_list if s not in PUBLIC and s < TRAIN_START]
    if other:
        raise ValueError(f"seed {other[0]} is in no seed set meant for tuning; allowed: public seeds (1000-1049) "
                         "or train seeds (1000000 and up)")
    return seed_list


@dataclass(frozen=True)
class TuningWorld:
    """One world of a study across worlds: its suite id, the suite whose constants normalize it, its scenario."""

    name: str
    suite: str
    config: ScenarioConfig


def tuning_worlds(spec: str | WorldSet) -> list[TuningWorld]:
    """The worlds of a ``--scenarios`` spec, if each is a training scenario of a suite, else ValueError saying why.

    The spec is resolved as training resolves it (:func:`wfbench.train.worlds.world_set`:
    ``suite-v1:train``, or comma-separated scenarios; a held-out scenario or split is refused
    there), or given resolved as a :class:`~wfbench.train.worlds.WorldSet`. Each world must
    have a suite's normalization constants, since the objective is the mean normalized score.
    """
    ws = spec if isinstance(spec, WorldSet) else world_set(spec)
    spec = ws.name
    out = []
    for w in ws.worlds:
        suite = w.suite  # the suite that holds the world (only its training scenarios get this far)
        if suite is None:
            allowed = "; ".join(f"{name}:train or its ids ({', '.join(s.ids('train'))})"
                                for name, s in SUITES.items())
            raise ValueError(f"scenarios {spec!r}: {w.name} is in no suite's training split, so it has no "
                             f"normalized score to tune on; allowed: {allowed}")
        out.append(TuningWorld(w.name, suite, w.config))
    return out


def _number(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{what}: {text!r} is not a finite number")
    return v


def search_space(policy: Any, params: str | Iterable[str] | Mapping[str, Any] | None = None) -> dict[str, Param]:
    """The parameters to search and their ranges.

    Args:
        policy: a policy with ``tunable`` (a composite of built-in kernels).
        params: ``None`` for all of ``policy.tunable``; else the names to search, as a
            comma-separated string or a sequence, each optionally narrowed as
            ``name=low:high``, or a mapping name -> ``(low, high)`` or ``None``.

    Raises:
        ValueError: a name the policy does not declare, or a range that is not inside
            the declared one; the message lists what is allowed.
    """
    allowed: dict[str, Param] = dict(getattr(policy, "tunable", {}) or {})
    name = getattr(policy, "name", type(policy).__name__)
    if not allowed:
        raise ValueError(f"policy {name!r} declares no tunable parameters; allowed: a composite of built-in kernels "
                         "with parameters (see 'wfbench policies', for example heuristic or solver)")
    if params is None:
        return allowed
    items: list[tuple[str, Any]]
    if isinstance(params, Mapping):
        items = list(params.items())
    else:
        entries = params.split(",") if isinstance(params, str) else list(params)
        items = []
        for entry in (e.strip() for e in entries):
            if not entry:
                continue
            key, sep, rng = entry.partition("=")
            if sep:
                low, colon, high = rng.partition(":")
                if not colon:
                    raise ValueError(f"parameter range {entry!r}: write it as name=low:high")
                items.append((key.strip(), (_number(low, f"low of {key.strip()}"),
                                            _number(high, f"high of {key.strip()}"))))
            else:
                items.append((key, None))
    if not items:
        raise ValueError(f"no parameters named; allowed: {', '.join(allowed)}")
    space: dict[str, Param] = {}
    for key, rng in items:
        if key not in allowed:
            raise ValueError(f"policy {name!r} has no tunable parameter {key!r}; allowed: {', '.join(allowed)}")
        space[key] = allowed[key] if rng is None else allowed[key].narrowed(float(rng[0]), float(rng[1]), key)
    return space


def _suggest(trial: optuna.Trial, key: str, p: Param) -> float | int:
    if p.type == "int":
        return trial.suggest_int(key, int(p.low), int(p.high), log=p.log)
    return trial.suggest_float(key, p.low, p.high, log=p.log)


def check_scenario_args(scenario: Any, scenarios: Any, names: tuple[str, str] = ("scenario", "scenarios")) -> None:
    """ValueError unless exactly one of ``scenario`` and ``scenarios`` is given (``names``: as messages say them)."""
    if scenario is not None and scenarios is not None:
        raise ValueError(f"{names[0]} and {names[1]} do not go together: give one scenario, or the worlds to tune "
                         "across")
    if scenario is None and scenarios is None:
        raise ValueError(f"give a {names[0]} or {names[1]} (worlds to tune across, e.g. 'suite-v1:train'), not "
                         "neither")


def default_study_name(policy: str, where: str) -> str:
    """The study's name when none is given: ``POLICY@SCENARIO``, or ``POLICY@SPEC`` across worlds."""
    return f"{policy}@{where}"


def default_out(policy: str, where: str) -> Path:
    """The tuned-policy file when none is given: ``tuned-POLICY-WHERE.json`` in the current folder.

    ``where`` is the scenario's name, or the spec of the worlds with every run of characters
    other than letters, digits, ``_``, ``.`` and ``-`` made one ``-`` (``suite-v1:train`` gives
    ``tuned-heuristic-suite-v1-train.json``).
    """
    return Path(f"tuned-{policy}-{re.sub(r'[^A-Za-z0-9_.-]+', '-', where)}.json")


def _space_attr(space: dict[str, Param]) -> dict[str, dict[str, Any]]:
    return {k: {"low": p.low, "high": p.high, "type": p.type, "log": p.log} for k, p in space.items()}


def tune(policy: str, scenario: str | ScenarioConfig | None = None, trials: int = 100,
         seeds: int | str | Iterable[int] = "public",
         params: str | Iterable[str] | Mapping[str, Any] | None = None, study_db: str | Path = DEFAULT_DB,
         study_name: str | None = None, execution: Execution | None = None, sampler_seed: int = 0,
         out: str | Path | Literal[False] | None = None, name: str | None = None,
         command: str | None = None, scenarios: str | WorldSet | None = None) -> TuneResult:
    """Search ``policy``'s tunable parameters for the highest mean NSW over ``seeds``.

    Or, with ``scenarios``, for the highest mean normalized score over several worlds.

    Args:
        policy: a registry name or ``D+W+P`` composite whose parts declare parameters
            (``heuristic``, ``solver``, ...). It is recorded as the file's base.
        scenario: a scenario name (a preset, a suite's scenario id or a config file;
            :func:`wfbench.scenarios.resolve.resolve_scenario`), recorded as it is, or a
            :class:`ScenarioConfig`, recorded by its name.
        trials: the study's total of finished trials; a resumed study runs the rest.
        seeds: tuning seeds, public (default) or train; test seeds are refused.
        params: which parameters to search and optional narrower ranges
            (:func:`search_space`); default all that the policy declares.
        study_db: the SQLite file that holds the study.
        study_name: the study's name in it (default ``POLICY@SCENARIO``, :func:`default_study_name`).
        execution: where each trial's evaluation runs (backend, workers, threads, address,
            chunk size; :class:`~wfbench.harness.backends.Execution`), and with its
            ``progress`` a bar over the trials; ``None``: serial, all cores, no bar.
        sampler_seed: seed of the TPE sampler.
        out: write the tuned-policy file here (.json or .toml); ``None`` (default): to
            ``tuned-POLICY-SCENARIO.json`` in the current folder, as ``wfbench tune`` does
            (:func:`default_out`); ``False``: do not write.
        name: the tuned policy's name (default ``POLICY-tuned``).
        command: the command that made it, recorded in the file.
        scenarios: instead of ``scenario``, the worlds to tune across (:func:`tuning_worlds`:
            ``"suite-v1:train"`` or comma-separated training scenarios); each trial's score
            is the mean over the worlds of its mean normalized score on ``seeds``. The spec
            (or a :class:`~wfbench.train.worlds.WorldSet`, resolved already) is recorded
            as the file's scenario.

    Raises:
        ValueError: a bad policy, scenario, seed list, parameter, range, trial count,
            output path, a held-out or unnormalized world, both or neither of ``scenario``
            and ``scenarios``, or a study of that name made with other settings.
    """
    if not isinstance(policy, str):
        raise ValueError("policy must be a registry name or a D+W+P composite (it is recorded as the file's base)")
    if tuned_file.is_tuned_spec(policy):
        raise ValueError(f"{policy!r} is a tuned-policy file: tune its base policy instead (its 'base' field)")
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
        raise ValueError(f"trials = {trials!r}: allowed: a whole number >= 1")
    if isinstance(sampler_seed, bool) or not isinstance(sampler_seed, int) or sampler_seed < 0:
        raise ValueError(f"sampler_seed = {sampler_seed!r}: allowed: a whole number >= 0")
    check_scenario_args(scenario, scenarios)
    run = check_execution(execution, Execution())
    each = run.replace(progress=False)  # the bar is over the trials, not over each trial's episodes
    worlds: list[TuningWorld] | None = None
    if scenarios is not None:
        worlds = tuning_worlds(scenarios)
        scenario_name = slug = scenarios.name if isinstance(scenarios, WorldSet) else scenarios
    else:
        config = resolve_scenario(scenario)
        scenario_name = scenario if isinstance(scenario, str) else config.name
        slug = config.name
    seed_list = check_tuning_seeds(seeds)
    base = get(policy)
    space = search_space(base, params)
    out_path = None if out is False else default_out(policy, slug) if out is None else Path(out)
    if out_path is not None:
        if out_path.suffix.lower() not in tuned_file.SUFFIXES:
            raise ValueError(f"output {str(out_path)!r}: allowed suffixes: {', '.join(tuned_file.SUFFIXES)}")
        if not out_path.parent.is_dir():
            raise ValueError(f"output {str(out_path)!r}: folder {str(out_path.parent)!r} does not exist")
    db = Path(study_db)
    if not db.parent.is_dir():
        raise ValueError(f"study database {str(db)!r}: folder {str(db.parent)!r} does not exist")
    study_name = study_name or default_study_name(policy, scenario_name)
    tuned_name = name or f"{policy}-tuned"
    settings = {"policy": policy, "scenario": scenario_name, "seeds": seed_list, "space": _space_attr(space),
                "objective": OBJECTIVE if worlds is None else OBJECTIVE_WORLDS}
    if worlds is not None:  # the worlds as resolved, so that a spec whose meaning changed is not resumed
        settings["worlds"] = [w.name for w in worlds]

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = f"sqlite:///{db.resolve()}"
    existing = {s.study_name: s for s in optuna.get_all_study_summaries(storage)} if db.exists() else {}
    held = existing[study_name].n_trials if study_name in existing else 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        sampler = optuna.samplers.TPESampler(seed=sampler_seed + held, multivariate=True)
    study = optuna.create_study(storage=storage, study_name=study_name, direction="maximize", sampler=sampler,
                                load_if_exists=True)
    if study_name in existing:
        before = {k: study.user_attrs.get(k) for k in settings}
        diff = [k for k in settings if before[k] != settings[k]]
        if diff:
            raise ValueError(f"study {study_name!r} in {str(db)!r} was made with another {', '.join(diff)} "
                             f"({'; '.join(f'{k}: {before[k]!r}' for k in diff if k != 'seeds')}); run it with "
                             "the same settings to resume, or name a new study with --study-name")
    else:
        for k, v in settings.items():
            study.set_user_attr(k, v)
        start = {k: v for k, v in base.params().items() if k in space}
        if all(space[k].low <= v <= space[k].high for k, v in start.items()):
            study.enqueue_trial(start, user_attrs={"untuned": True})

    def objective(trial: optuna.Trial) -> float:
        values = {k: _suggest(trial, k, p) for k, p in space.items()}
        candidate = base.with_params(values, name=f"{tuned_name}#{trial.number}")
        if worlds is None:
            df = evaluate(candidate, config, seed_list, act_timeout_s=None, execution=each)
            return float(df["nsw"].mean())
        per_world = {}
        for w in worlds:
            df = evaluate(candidate, w.config, seed_list, act_timeout_s=None, execution=each)
            per_world[w.name] = float(normalize(float(df["nsw"].mean()), w.name, w.suite))
        trial.set_user_attr("world_scores", per_world)
        return float(np.mean(list(per_world.values())))

    def finished() -> int:
        return sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.get_trials(deepcopy=False))

    done_before = finished()
    remaining = max(0, trials - done_before)
    if remaining:
        bar = tqdm(total=trials, initial=done_before, desc=f"tune {policy} on {scenario_name}", unit="trial",
                   disable=not run.progress, leave=False)

        def on_trial(st: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
            if trial.state == optuna.trial.TrialState.COMPLETE:
                bar.update(1)
                bar.set_postfix(best=f"{st.best_value:.4f}", refresh=False)

        try:
            study.optimize(objective, n_trials=remaining, callbacks=[on_trial])
        finally:
            bar.close()
    complete = [t for t in study.get_trials(deepcopy=False) if t.state == optuna.trial.TrialState.COMPLETE]
    best = study.best_trial
    first = next((t for t in complete if t.user_attrs.get("untuned")), None)
    untuned = first.value if first is not None else None
    chosen = base.with_params(best.params, name=tuned_name)
    result = tuned_file.TunedPolicy(
        name=tuned_name, base=policy, params=chosen.params(), scenario=scenario_name, seeds=seed_list,
        trials=len(complete), best_score=float(best.value), objective=settings["objective"],
        seed_set=describe(seed_list), wfbench_version=__version__,
        command=command or f"wfbench tune {shlex.quote(policy)} --scenario{'s' if worlds else ''} "
                           f"{shlex.quote(scenario_name)} --trials {trials} (Python: wfbench.tune.tune)",
        study_name=study_name, sampler_seed=sampler_seed,
        extra={"searched": _space_attr(space), "best_trial": best.number,
               **({"untuned_score": untuned} if untuned is not None else {}),
               **({"worlds": settings["worlds"], "world_scores": best.user_attrs["world_scores"],
                   **({"untuned_world_scores": first.user_attrs["world_scores"]} if first is not None else {})}
                  if worlds is not None else {})},
    )
    if out_path is not None:
        tuned_file.write(result, out_path)
    return TuneResult(result, out_path, study_name, db, finished() - done_before, untuned)
