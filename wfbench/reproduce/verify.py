"""Committed results against what the code computes now: recompute pieces of a suite run and compare bit for bit.

:func:`verify` plays chosen seeds of chosen pieces of a run's ``cache/`` (``docs/results/suite-v1-50``)
again with the installed code and compares every result column (KPIs, utilities, counters; not
the budget columns, which are measurements) to the bit; one differing number fails the piece.
``wfbench reproduce verify --out FOLDER`` checks every piece on its first seed. :data:`CI_SAMPLE`
is what CI recomputes (``tests/reproduce/test_committed_results.py``): every policy of the run on
one piece, every scenario but ``city``, one seed each, spread over both halves of the 50 seeds
(``docs/suite.md``, "What moved in issue #42").
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.core.kpis import SCORE
from wfbench.core.seeds import resolve_seeds
from wfbench.harness.backends import Execution
from wfbench.harness.budget import results_only
from wfbench.reproduce.common import Output, Progress
from wfbench.scenarios import SuiteScenario, get_suite

# (policy, scenario id, test seed): every policy, training seed, the oracle and the bound once, each scenario but
# city at least twice, seeds over both halves of a 2-worker run; ppo-general on large seed 0 and
# hindsight-general#seed4 on table2-g32-f100-s25 seed 9 are the pieces issue #42 found stale
CI_SAMPLE: tuple[tuple[str, str, int], ...] = (
    ("random", "small-v1", 3),
    ("heuristic", "real-benelux-v1", 20),
    ("heuristic-stochastic", "real-nyc-v1", 37),
    ("solver", "clustered-64-v1", 4),
    ("heuristic-tuned", "novice-64-v1", 21),
    ("solver-tuned", "surge-64-v1", 38),
    ("heuristic-tuned-train", "churn-64-v1", 5),
    ("solver-tuned-train", "table2-g256-f25-s5-v1", 22),
    ("ppo-joint", "slow-64-v1", 39),
    ("ppo-dispatch", "table2-g32-f25-s10-v1", 6),
    ("impala-joint", "table2-g32-f100-s25-v1", 23),
    ("hindsight-joint", "nonstationary-v1", 40),
    ("ppo-independent", "table2-g128-f50-s25-v1", 7),
    ("hindsight-ppo", "paper-64-v1", 24),
    ("ppo-general", "large-v1", 0),
    ("ppo-general#seed0", "small-v1", 8),
    ("ppo-general#seed1", "real-benelux-v1", 25),
    ("ppo-general#seed2", "real-nyc-v1", 42),
    ("ppo-general#seed3", "clustered-64-v1", 9),
    ("ppo-general#seed4", "novice-64-v1", 26),
    ("hindsight-general", "surge-64-v1", 43),
    ("hindsight-general#seed0", "churn-64-v1", 10),
    ("hindsight-general#seed1", "table2-g256-f25-s5-v1", 27),
    ("hindsight-general#seed2", "slow-64-v1", 44),
    ("hindsight-general#seed3", "table2-g32-f25-s10-v1", 11),
    ("hindsight-general#seed4", "table2-g32-f100-s25-v1", 9),
    ("scalefree-general", "nonstationary-v1", 45),
    ("scalefree-general#seed0", "table2-g128-f50-s25-v1", 12),
    ("scalefree-general#seed1", "paper-64-v1", 29),
    ("scalefree-general#seed2", "large-v1", 46),
    ("scalefree-general#seed3", "small-v1", 13),
    ("scalefree-general#seed4", "real-benelux-v1", 30),
    ("distill-general", "churn-64-v1", 31),
    ("distill-general#seed0", "surge-64-v1", 15),
    ("distill-general#seed1", "table2-g32-f100-s25-v1", 32),
    ("distill-general#seed2", "clustered-64-v1", 19),
    ("distill-general#seed3", "novice-64-v1", 36),
    ("distill-general#seed4", "table2-g256-f25-s5-v1", 3),
    ("distill-switch-general", "real-nyc-v1", 26),
    ("distill-switch-general#seed0", "paper-64-v1", 7),
    ("distill-switch-general#seed1", "slow-64-v1", 38),
    ("distill-switch-general#seed2", "nonstationary-v1", 21),
    ("distill-switch-general#seed3", "large-v1", 41),
    ("distill-switch-general#seed4", "real-benelux-v1", 5),
    ("rollout-solver-tuned-1ms", "small-v1", 17),
    ("rollout-solver-tuned", "small-v1", 34),
    ("mpc-ma-calibrated", "table2-g32-f25-s10-v1", 18),
    ("search-scalefree-general-1ms", "paper-64-v1", 2),
    ("search-scalefree-general", "small-v1", 35),
    ("oracle", "real-nyc-v1", 47),
    ("oracle", "large-v1", 16),
    ("bound", "clustered-64-v1", 14),
)


@dataclass(frozen=True)
class Piece:
    """One committed piece: ``policy`` on ``scenario``, its rows in ``path``."""

    policy: str
    scenario: SuiteScenario
    path: Path

    def rows(self) -> pd.DataFrame:
        return pd.read_csv(self.path, float_precision="round_trip")  # the same bits as the run that wrote it

    def meta(self) -> dict:
        return json.loads(self.path.with_suffix(".json").read_text())


def _known_policies() -> list[str]:
    from wfbench.reproduce.suite import default_policies, with_members

    return [*with_members(default_policies())[0], "bound"]


def pieces(folder: Path, policies: Sequence[str] | None = None, scenarios: Sequence[str] | None = None,
           suite_name: str = "suite-v1") -> list[Piece]:
    """The committed pieces under ``folder/cache`` (of these policies and scenarios, default all), in order.

    A piece's folder is its policy's name made path-safe (``ppo-general#seed0`` in
    ``ppo-general_seed0``); it is read back against the suite's policies and the names given.
    """
    suite = get_suite(suite_name)
    chosen = [suite.scenario(x) for x in scenarios] if scenarios else list(suite.scenarios)
    from wfbench.reproduce.pieces import piece_folder

    by_dir = {piece_folder(p): p for p in [*_known_policies(), *(policies or [])]}
    wanted = set(policies) if policies else None
    out = []
    for d in sorted(p for p in (folder / "cache").iterdir() if p.is_dir()) if (folder / "cache").is_dir() else []:
        policy = by_dir.get(d.name)
        if policy is None or (wanted is not None and policy not in wanted):
            continue
        for sc in chosen:
            path = d / f"{sc.id}.csv"
            if path.exists() and path.with_suffix(".json").exists():
                out.append(Piece(policy, sc, path))
    return out


def recompute(policy: str, scenario: SuiteScenario, seeds: Sequence[int],
              execution: Execution | None = None) -> pd.DataFrame:
    """The rows ``policy`` gives now on ``seeds`` of ``scenario`` (the bound: its score column alone)."""
    from wfbench.harness.evaluation import evaluate
    from wfbench.policies.registry import ScenarioMismatchWarning

    if policy == "bound":
        from wfbench.core.bound import score_upper_bound

        return pd.DataFrame({"seed": list(seeds), SCORE: score_upper_bound(scenario.config, list(seeds))})
    with warnings.catch_warnings():  # the networks run zero-shot on purpose, as in the suite run
        warnings.simplefilter("ignore", ScenarioMismatchWarning)
        return evaluate(policy, scenario.config, list(seeds), execution=execution or Execution())


def differences(committed: pd.DataFrame, now: pd.DataFrame) -> list[str]:
    """Each result column and seed where ``now`` differs from ``committed`` by any bit: ``column seed S: a -> b``."""
    old = results_only(committed).set_index("seed")
    new = results_only(now).set_index("seed")
    out = []
    missing = sorted(set(old.columns) ^ set(new.columns))
    if missing:
        out.append(f"columns differ: {missing}")
    for seed in new.index:
        if seed not in old.index:
            out.append(f"seed {seed}: not in the committed piece")
            continue
        for col in sorted(set(old.columns) & set(new.columns)):
            a, b = old.at[seed, col], new.at[seed, col]
            same = (a == b) or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))
            if not same:
                out.append(f"{col} seed {seed}: {a!r} -> {b!r}")
    return out


@dataclass
class Verdict:
    """One piece checked: its policy, scenario id, the seeds played, the differences (empty: identical)."""

    policy: str
    scenario: str
    seeds: list[int]
    differences: list[str]
    seconds: float
    provenance: dict | None


def verify(out: Path, runs: int = 1, execution: Execution | None = None, progress: Progress = None,
           seeds: Sequence[int] | None = None, policies: Sequence[str] | None = None,
           scenarios: Sequence[str] | None = None, suite_name: str = "suite-v1",
           sample: Sequence[tuple[str, str, int]] | None = None, **_: object) -> Output:
    """Recompute pieces of the suite run in ``out`` and compare them bit for bit; the text lists each piece.

    Args:
        out: the suite run's folder (its ``cache/``); nothing is written into it.
        runs: without ``seeds``, the first ``runs`` seeds of each piece.
        execution: where the pieces are played again (default serial); results do not depend
            on it. Its Ray address is not used: the pieces run on a local Ray instance.
        progress: called with the name of each piece as it starts.
        seeds: the seeds to play again (a set name or a list; each must be in the piece).
        policies: narrow the pieces to these policies (default: all of the folder).
        scenarios: narrow the pieces to these scenario ids (default: all).
        suite_name: the suite the folder's scenarios belong to.
        sample: (policy, scenario id, seed) triples instead of the above (e.g. :data:`CI_SAMPLE`).

    Returns:
        The :class:`Output` (``files`` empty) with ``verdicts`` (a list of :class:`Verdict`) set.
    """
    execution = (execution or Execution()).replace(address=None, progress=False)
    suite = get_suite(suite_name)
    if sample is not None:
        todo = []
        for policy, sc_id, seed in sample:
            found = pieces(out, [policy], [sc_id], suite_name)
            if not found:
                raise ValueError(f"no committed piece of {policy!r} on {sc_id!r} in {out / 'cache'}")
            todo.append((found[0], [seed]))
    else:
        todo = []
        for piece in pieces(out, policies, scenarios, suite_name):
            have = piece.rows()["seed"].tolist()
            chosen = list(resolve_seeds(seeds)) if seeds is not None else have[:runs]
            absent = [s for s in chosen if s not in have]
            if absent:
                raise ValueError(f"seeds {absent} are not in the piece {piece.path} (it has {len(have)} seeds)")
            todo.append((piece, chosen))
    verdicts, lines = [], []
    for piece, chosen in todo:
        if progress:
            progress(f"{piece.scenario.id}: {piece.policy}")
        t0 = time.perf_counter()
        now = recompute(piece.policy, piece.scenario, chosen, execution)
        committed = piece.rows()
        diffs = differences(committed[committed["seed"].isin(chosen)], now)
        v = Verdict(piece.policy, piece.scenario.id, chosen, diffs, time.perf_counter() - t0,
                    piece.meta().get("provenance"))
        verdicts.append(v)
        made = (v.provenance or {}).get("commit") or "unrecorded"
        state = "same bits" if not diffs else f"{len(diffs)} differences, first: {diffs[0]}"
        lines.append(f"{v.scenario:24s} {v.policy:26s} seeds {','.join(map(str, chosen))}: {state} "
                     f"(made by {made[:12]}, {v.seconds:.1f} s)")
    bad = sum(1 for v in verdicts if v.differences)
    lines.append(f"{len(verdicts)} pieces of {suite.name} recomputed from {out}: {bad} differ from the committed "
                 "results")
    result = Output("\n".join(lines), [])
    result.verdicts = verdicts  # type: ignore[attr-defined]
    return result
