"""Table 3: the paper's rows 1-7 on paper-64 beside wfbench's solver, tuned, learned and oracle rows and the bound.

Rows 1-7 carry the paper's own names of their decisions (``paper.toml``); every other
row names its decisions as the policy registry does (:func:`wfbench.policies.registry.parts`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wfbench.analysis.tables import markdown_table
from wfbench.core.kpis import KPI_LABELS, KPI_NAMES
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate, format_kpi, summarize
from wfbench.policies.registry import LINEUPS, learned_names, names_of, parts
from wfbench.reproduce.common import DIRECTION, PROCESS, Output, Progress, write
from wfbench.reproduce.paper import table3_rows

# our policy for each of the paper's rows (the learned ones: docs/rl.md)
TABLE3_POLICIES = {"1": "random", "2": "random-dispatch", "3": "random-positioning", "4": "heuristic",
                   "5": "ppo-dispatch", "6": "ppo-joint", "7": "impala-joint"}
SOLVER_ROWS = [(f"S{i}", p) for i, p in enumerate(LINEUPS["table3-solver"], 1)]
ORACLE_ROWS = [(f"O{i}", p) for i, p in enumerate(LINEUPS["table3-oracle"], 1)]
# beyond the paper: the heuristic and solver composites with their parameters tuned on the public seeds
# (wfbench tune, policies/tuned/, docs/policies.md#tuning)
TUNED_ROWS = [(f"T{i}", p) for i, p in enumerate(LINEUPS["table3-tuned"], 1)]
# beyond the paper: the shipped networks that are not rows 5-7 (docs/rl.md, docs/hindsight-learning.md); a row
# whose checkpoint is not shipped says so, like rows 5-7
LEARNED_ROWS = [("L1", "ppo-independent"), ("L2", "hindsight-joint"), ("L3", "hindsight-ppo")]


def _shipped(policy: str) -> bool:
    """False for a learned policy whose checkpoint is not shipped; True for every other policy."""
    return policy not in names_of("learned") or policy in learned_names()


def size() -> int:
    """The evaluations :func:`table3` runs with its default rows (for a progress bar): rows, tuned, oracles, bound."""
    paper = [r for r in table3_rows() if _shipped(TABLE3_POLICIES[r.row])]
    learned = [n for _, n in LEARNED_ROWS if _shipped(n)]
    return len(paper) + len(SOLVER_ROWS) + len(TUNED_ROWS) + len(learned) + len(ORACLE_ROWS) + 1


def table3(out: Path, runs: int = 50, execution: Execution = PROCESS, progress: Progress = None,
           solver_rows: bool = True, oracle_rows: bool = True, tuned_rows: bool = True,
           learned_rows: bool = True) -> Output:
    """The paper's rows 1-4 (exactly its combinations), the solver rows and the RL rows 5-7.

    Beyond the paper, rows T1-T2: the heuristic and solver composites tuned on the public
    seeds (``wfbench tune``; the files in ``policies/tuned/``); rows L1-L3: the other
    shipped networks (independent agents, hindsight learning, PPO improved by hindsight
    learning).

    Then the hindsight oracles and the proven upper bound on NSW (docs/hindsight.md): not
    deployable, a reference.
    """
    seeds = list(range(runs))
    header = ["#", "Dispatch", "Workforce mgmt", "Positioning", *[KPI_LABELS[k] for k in KPI_NAMES],
              "Paper: WC / PUR / AFD / NSW (cost)"]
    rows, records = [], []

    def run(num: str, policy: str, cells: tuple[str, ...], paper_text: str, paper_cell: str) -> None:
        if progress:
            progress(policy)
        summ = summarize(evaluate(policy, "paper-64", seeds, execution=execution))
        rows.append([num, *cells, *[format_kpi(*summ[k]) for k in KPI_NAMES], paper_cell])
        records.append({"row": num, "policy": policy, **{k: summ[k][0] for k in KPI_NAMES},
                        **{f"{k}_q25": summ[k][1] for k in KPI_NAMES}, **{f"{k}_q75": summ[k][2] for k in KPI_NAMES},
                        "paper": paper_text})

    def not_shipped(num: str, cells: tuple[str, ...], paper_cell: str) -> None:  # a network whose file is absent
        rows.append([num, *cells, "not shipped yet (RL)", *["-"] * (len(KPI_NAMES) - 1), paper_cell])

    def run_or_say(num: str, policy: str, cells: tuple[str, ...], paper_text: str, paper_cell: str) -> None:
        if _shipped(policy):
            run(num, policy, cells, paper_text, paper_cell)
        else:
            not_shipped(num, cells, paper_cell)

    for r in table3_rows():
        run_or_say(r.row, TABLE3_POLICIES[r.row], r.parts, r.text, r.text)
    ours = ((solver_rows, SOLVER_ROWS, "(not in the paper)"),
            (tuned_rows, TUNED_ROWS, "(beyond the paper: tuned on public seeds)"),
            (learned_rows, LEARNED_ROWS, "(beyond the paper: trained on paper-64)"),
            (oracle_rows, ORACLE_ROWS, "(not in the paper; reads the future)"))
    for wanted, group, paper_cell in ours:
        for num, policy in group if wanted else ():
            run_or_say(num, policy, parts(policy), "", paper_cell)
    if oracle_rows:
        from wfbench.core.bound import score_upper_bound
        from wfbench.core.config import ScenarioConfig

        if progress:
            progress("bound")
        bound = score_upper_bound(ScenarioConfig.preset("paper-64"), seeds)
        q25, q75 = np.percentile(bound, [25, 75])
        rows.append(["B", "Upper bound", "(proven, any policy)", "", *["-"] * (len(KPI_NAMES) - 1),
                     format_kpi(float(bound.mean()), q25, q75), "(not in the paper)"])
        records.append({"row": "B", "policy": "bound", "nsw": float(bound.mean()), "nsw_q25": q25, "nsw_q75": q75,
                        "paper": ""})
    md = "\n".join([
        f"Table 3: paper-64, seeds 0-{runs - 1}; KPIs mean (25%-75%) over runs. Rows 1-4 are the paper's "
        "combinations; rows 5-7 are the shipped ppo-dispatch, ppo-joint and impala-joint checkpoints "
        "(docs/rl.md; a row whose checkpoint is not shipped says so); S1-S4 are wfbench's solver rows; "
        "T1-T2 (beyond the paper) are the heuristic and solver composites with their parameters tuned on the "
        "public seeds 1000-1049 (wfbench tune, docs/policies.md); L1-L3 (beyond the paper) are the other shipped "
        "networks: independent agents, hindsight learning, and ppo-joint with its workforce head improved by "
        "hindsight learning (docs/hindsight-learning.md); "
        "O1-O2 are hindsight oracles (they read the episode's future: not deployable) and B is a proven upper "
        "bound on NSW per seed (docs/hindsight.md).",
        "", markdown_table(header, rows), "", DIRECTION,
    ])
    return Output(md, write(out, "table3", md, pd.DataFrame(records)))
