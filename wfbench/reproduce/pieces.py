"""A suite run's pieces: found where stored, extended by only the seeds they lack, planned before they are played.

A piece is one (policy, scenario) result over seeds: ``cache/POLICY/SCENARIO.csv`` (one row per
seed, the evaluator's columns) beside a ``.json`` holding the scenario's ``hash``, the ``seeds``,
``wall_s`` and the ``provenance`` (:mod:`wfbench.reproduce.provenance`). :func:`find` takes a
stored piece of the same hash that holds the chosen seeds and cuts it to them. :func:`obtain`
plays only the seeds no stored piece holds and writes the merged piece, whose ``parts`` say which
seeds each provenance made: a seed's row does not depend on the batch it was played in
(:mod:`wfbench.harness.backends`), so 20 committed seeds and 30 new ones make the same 50 rows as
one run would. :func:`plan` lists what is missing with an estimate of its CPU time from the stored
pieces' own cost, so a long job says what it will play before it starts. docs/suite.md, "How to
run", explains the folders.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from wfbench.core.kpis import SCORE
from wfbench.harness.backends import Execution
from wfbench.reproduce import provenance
from wfbench.scenarios import SuiteScenario
from wfbench.scenarios import pieces as stored
from wfbench.scenarios.pieces import parts_of, piece_folder, read_rows


def piece_path(out: Path, policy: str, scenario: SuiteScenario) -> Path:
    """Where ``policy``'s piece of ``scenario`` is stored in the run folder ``out``."""
    return stored.piece_path(out, policy, scenario.id)


def _meta(path: Path, scenario: SuiteScenario) -> dict | None:
    return stored.read_meta(path, scenario.hash)


def provenance_of(meta: dict, seed: int) -> dict | None:
    """The provenance of the part of a piece that played ``seed``."""
    for part in parts_of(meta):
        if seed in part["seeds"]:
            return part.get("provenance")
    return None


def _stored(folders: Sequence[Path], policy: str, scenario: SuiteScenario,
            seeds: Sequence[int]) -> tuple[pd.DataFrame, dict] | None:
    """The stored piece holding the most of ``seeds`` (the first such folder on a tie), or None.

    Its rows of those seeds in the order asked, and its parts cut to them (``wall_s`` scaled to
    the seeds taken).
    """
    best = None
    for folder in folders:
        path = piece_path(folder, policy, scenario)
        m = _meta(path, scenario)
        if m is None:
            continue
        held = set(m.get("seeds", []))
        have = [s for s in seeds if s in held]
        if have and (best is None or len(have) > len(best[2])):
            best = (path, m, have)
    if best is None:
        return None
    path, m, have = best
    df = read_rows(path).set_index("seed").loc[have].reset_index()
    taken = set(have)
    parts = []
    for p in parts_of(m):
        mine = [s for s in p["seeds"] if s in taken]
        if mine:
            wall = p.get("wall_s")
            parts.append({**p, "seeds": mine,
                          "wall_s": None if wall is None else wall * len(mine) / max(1, len(p["seeds"]))})
    return df, {"parts": parts}


def _with_wall(df: pd.DataFrame, meta: dict) -> pd.DataFrame:
    walls = [p["wall_s"] for p in meta["parts"]]
    df.attrs["wall_s"] = None if any(w is None for w in walls) else sum(walls)
    return df


def find(folders: Sequence[Path], policy: str, scenario: SuiteScenario, seeds: Sequence[int]) -> pd.DataFrame | None:
    """The first stored piece of (policy, scenario) of this scenario hash whose seeds include ``seeds``, cut to them.

    ``attrs["wall_s"]`` is the piece's wall time scaled to the seeds taken.
    """
    seeds = [int(s) for s in seeds]
    found = _stored(folders, policy, scenario, seeds)
    if found is None or len(found[0]) < len(seeds):
        return None
    return _with_wall(*found)


def store(path: Path, df: pd.DataFrame, policy: str, scenario: SuiteScenario, seeds: Sequence[int],
          wall_s: float, earlier: Sequence[dict] = (), batches: Sequence[Sequence[int]] | None = None) -> None:
    """Write a piece and its ``.json``; ``earlier`` are the parts (seeds, provenance) its older rows came from.

    ``batches``: the batches the new seeds were played in, each in its order (a network's
    totals depend on its batch, so the replaying oracle reads them only in the same one).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False)
    now = {"seeds": [int(s) for s in seeds], "wall_s": wall_s, "provenance": provenance.current(policy)}
    if batches is not None:
        now["batches"] = [[int(s) for s in b] for b in batches]
    meta = {"hash": scenario.hash, "seeds": [int(s) for s in df["seed"]],
            "wall_s": wall_s + sum(p.get("wall_s") or 0.0 for p in earlier), "provenance": now["provenance"]}
    if "batches" in now:
        meta["batches"] = now["batches"]
    if earlier:
        meta["parts"] = [*earlier, now]
    path.with_suffix(".json").write_text(json.dumps(meta))


def play(policy: str, scenario: SuiteScenario, seeds: Sequence[int],
         execution: Execution) -> tuple[pd.DataFrame, float]:
    """Play ``policy`` (or the proven ``bound``) on ``seeds`` of ``scenario``: its rows and the wall seconds."""
    from wfbench.harness.evaluation import evaluate
    from wfbench.policies.registry import ScenarioMismatchWarning

    t0 = time.perf_counter()
    if policy == "bound":
        from wfbench.core.bound import score_upper_bound

        df = pd.DataFrame({"seed": list(seeds), SCORE: score_upper_bound(scenario.config, list(seeds))})
    else:
        with warnings.catch_warnings():  # the networks run zero-shot on purpose: the mismatch is the point
            warnings.simplefilter("ignore", ScenarioMismatchWarning)
            df = evaluate(policy, scenario.config, list(seeds), execution=execution)
    return df, time.perf_counter() - t0


def obtain(folders: Sequence[Path], out: Path, policy: str, scenario: SuiteScenario, seeds: Sequence[int],
           execution: Execution, play_fn=None) -> pd.DataFrame:
    """The piece of (policy, scenario) over ``seeds``: found, or its missing seeds played and merged into ``out``.

    ``folders`` are searched in order (``out`` first, as a rule). What is played is written to
    ``out``'s cache with the earlier rows it extends, so the next run finds all of it; the rows
    ``out``'s piece held of other seeds stay in it (``--seeds 10-19`` after ``--seeds 0-9``
    leaves a piece of 0-19, with a part per run).
    ``play_fn`` replaces :func:`play` (the suite passes its own, which tests replace).
    """
    seeds = [int(s) for s in seeds]
    part = _stored(folders, policy, scenario, seeds)
    have = [] if part is None else part[0]["seed"].tolist()
    if len(have) == len(seeds):  # every seed is stored: cut, nothing played
        return _with_wall(*part)
    missing = [s for s in seeds if s not in set(have)]
    new, wall_s = (play_fn or play)(policy, scenario, missing, execution)
    frames, asked = [new], []  # asked: the parts of the stored rows among ``seeds``
    if part is not None:
        frames.append(part[0])
        asked = part[1]["parts"]
    target = piece_path(out, policy, scenario)
    held = (_meta(target, scenario) or {}).get("seeds", [])
    kept = []  # out's piece keeps the seeds it held beyond those asked
    if others := [s for s in held if s not in set(seeds)]:
        rows, meta = _stored([out], policy, scenario, others)
        frames.append(rows)
        kept = meta["parts"]
    merged = pd.concat(frames, ignore_index=True).sort_values("seed", kind="stable").reset_index(drop=True)
    store(target, merged, policy, scenario, missing, wall_s, [*kept, *asked], new.attrs.get("batches"))
    merged = merged.set_index("seed").loc[seeds].reset_index()
    merged.attrs["wall_s"] = wall_s + sum(p.get("wall_s") or 0.0 for p in asked)  # the seeds asked only
    return merged


@dataclass(frozen=True)
class Missing:
    """Seeds of one (policy, scenario) that no stored piece holds, and what they should cost (CPU s, or None).

    ``source`` says where an estimate comes from when the policy has no piece of this scenario:
    ``(scenario, reference)``, its cost on that other scenario scaled by ``reference``'s cost on
    the two (``reference`` None: not scaled, no piece of a policy it builds on says how).
    """

    policy: str
    scenario: str
    seeds: tuple[int, ...]
    cpu_s: float | None
    source: tuple[str, str | None] | None = None


def _cpu_per_episode(folders: Sequence[Path], policy: str, scenario: SuiteScenario) -> float | None:
    """CPU s per episode of ``policy`` on ``scenario`` from its first stored piece there, else None."""
    for folder in folders:
        path = piece_path(folder, policy, scenario)
        if _meta(path, scenario) is not None:
            df = read_rows(path)
            if "cpu_s" in df:
                return float(df["cpu_s"].mean())
    return None


def _references(policy: str) -> list[str]:
    """The policies whose cost scales like ``policy``'s, nearest first (else none).

    A lookahead's siblings (the other presets of its kind on the same base, then any other
    policy on that base: on ``city`` the 10 ms rollout plays the sparse preset its 100 ms
    sibling and ``oracle-rollout`` play, where the dense base would say hundreds of hours),
    then its base, its base's base, ...
    """
    from wfbench.policies.registry import entry
    from wfbench.policies.table import TABLE

    chain: list[str] = []
    try:
        recipe = entry(policy).recipe
    except ValueError:  # "bound", a training seed (NAME#seedK), or a name the registry does not hold
        return chain
    base = getattr(recipe, "base", None)
    if base is not None:  # the same kind first (the other presets), then any other policy on the same base
        same = [n for n, e in TABLE.items() if n != policy and getattr(e.recipe, "base", None) == base]
        chain += sorted(same, key=lambda n: type(TABLE[n].recipe) is not type(recipe))
    name = policy
    while True:
        try:
            base = getattr(entry(name).recipe, "base", None)
        except ValueError:  # "bound", a training seed (NAME#seedK), or a name the registry does not hold
            return chain
        if base is None or base in chain:
            return chain
        chain.append(base)
        name = base


def _estimate(cost: Callable[[str, SuiteScenario], float | None], policy: str, scenario: SuiteScenario,
              others: Sequence[SuiteScenario]) -> tuple[float | None, tuple[str, str | None] | None]:
    """CPU s per episode of ``policy`` on ``scenario``, and where it comes from (:class:`Missing`'s ``source``).

    Its own stored cost there; else its cost on another scenario times the ratio of what a policy
    it builds on (:func:`_references`) costs on the two, taking the other scenario where that
    reference costs the closest (a lookahead's cost grows with its base's: ``search-*`` on
    ``city`` costs what the network's ratio of city to ``large`` says, not what it costs on
    ``large``); else its cost on another scenario as it is. ``cost``: :func:`_cpu_per_episode`
    of the plan's folders, memoized (a piece is read once however many estimates use it).
    """
    own = cost(policy, scenario)
    if own is not None:
        return own, None
    costs = {sc.id: c for sc in others if (c := cost(policy, sc)) is not None}
    if not costs:
        return None, None
    for ref in _references(policy):
        there = cost(ref, scenario)
        if not there:
            continue
        scaled = []
        for sc in others:
            if sc.id in costs and (r := cost(ref, sc)):
                scaled.append((abs(math.log(r / there)), sc.id, costs[sc.id] * there / r))
        if scaled:
            _, sid, est = min(scaled)
            return est, (sid, ref)
    sid = next(iter(costs))
    return costs[sid], (sid, None)


def plan(folders: Sequence[Path], policies: Sequence[str], scenarios: Sequence[SuiteScenario],
         seeds: Sequence[int], others: Sequence[SuiteScenario] | None = None,
         costs: Sequence[Path] = ()) -> list[Missing]:
    """What :func:`obtain` would play for each (policy, scenario), with its estimated CPU seconds.

    ``others``: the scenarios whose pieces an estimate may come from (default: the chosen ones;
    the callers pass the whole suite, so a scenario played alone is still estimated).
    ``costs``: more runs whose pieces an estimate may read, after ``folders`` (a suite's
    ``--out`` holds nothing yet; the committed runs know what a policy costs), never reused.
    """
    seeds = [int(s) for s in seeds]
    pool = list(scenarios) + [o for o in (others or []) if o.id not in {sc.id for sc in scenarios}]
    memo: dict[tuple[str, str], float | None] = {}
    readable = [*folders, *(c for c in costs if c not in folders)]

    def cost(policy: str, sc: SuiteScenario) -> float | None:
        if (policy, sc.id) not in memo:
            memo[policy, sc.id] = _cpu_per_episode(readable, policy, sc)
        return memo[policy, sc.id]

    todo = []
    for policy in policies:
        for sc in scenarios:
            part = _stored(folders, policy, sc, seeds)
            have = set() if part is None else set(part[0]["seed"])
            missing = tuple(s for s in seeds if s not in have)
            if not missing:
                continue
            per, source = _estimate(cost, policy, sc, [o for o in pool if o.id != sc.id])
            todo.append(Missing(policy, sc.id, missing, None if per is None else per * len(missing), source))
    return todo


def _where(m: Missing) -> str:
    if m.source is None:
        return ""
    other, ref = m.source
    if ref is None:
        return f" (its cost on {other}, not scaled)"
    return f" (its cost on {other}, scaled by {ref}'s cost there and here)"


def describe_plan(todo: Sequence[Missing], workers: int = 1) -> str:
    """The plan in a few lines: what will be played, and about how long it takes on ``workers`` workers."""
    if not todo:
        return "every piece is stored: nothing to play"
    known = [m.cpu_s for m in todo if m.cpu_s is not None]
    unknown = [m for m in todo if m.cpu_s is None]
    total = sum(known)
    head = f"to play: {len(todo)} pieces, {sum(len(m.seeds) for m in todo)} episodes; "
    if not known:
        head += "no stored piece of these policies to estimate their cost from"
    else:
        head += (f"about {_duration(total)} of CPU ({_duration(total / max(1, workers))} on {max(1, workers)} "
                 f"worker{'s' if workers != 1 else ''})")
        head += f", plus {len(unknown)} pieces with no stored cost to estimate from" if unknown else ""
    lines = [head]
    for m in sorted(todo, key=lambda m: -(m.cpu_s or 0.0))[:12]:
        lines.append(f"  {m.policy} on {m.scenario}: {len(m.seeds)} seeds, "
                     + ("cost unknown" if m.cpu_s is None else f"about {_duration(m.cpu_s)}{_where(m)}"))
    if len(todo) > 12:
        lines.append(f"  ... and {len(todo) - 12} more")
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


__all__ = ["Missing", "describe_plan", "find", "obtain", "parts_of", "piece_folder", "piece_path", "plan", "play",
           "provenance_of", "store"]
