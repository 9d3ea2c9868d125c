"""Paper reproduction commands, and the backends' argument errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from wfbench.cli import main
from wfbench.core.presets import TABLE2_CELLS, TABLE2_GRIDS
from wfbench.harness.backends import Execution
from wfbench.harness.evaluation import evaluate, results_only
from wfbench.reproduce.table2 import table2_trends
from wfbench.scenarios import Suite, get_suite

# identical numbers from the serial, process and Ray backends: tests/harness/test_backends_script.py, which
# runs them from a script without a __main__ guard, with a registry policy and a class from __main__


def test_the_run_options_are_one_execution_value_and_nothing_else():
    with pytest.raises(TypeError, match=r"^evaluate\(\) got an unexpected keyword argument 'backend'$"):
        evaluate("heuristic", "small", 2, backend="process")
    with pytest.raises(ValueError, match=r"^execution = 'process' is not allowed; allowed: an Execution or None$"):
        evaluate("heuristic", "small", 2, execution="process")


@pytest.mark.parametrize(("options", "message"), [
    ({"backend": "gpu"}, "unknown backend 'gpu'; available: serial, process, ray"),
    ({"address": "auto"}, "address='auto' only applies to backend 'ray'"),
    ({"workers": 0}, r"workers = 0 is not allowed; allowed: None or an integer >= 1"),
    ({"threads": 1.5}, r"threads = 1.5 is not allowed; allowed: None or an integer >= 1"),
    ({"chunk_size": True}, r"chunk_size = True is not allowed; allowed: None or an integer >= 1"),
    ({"progress": "yes"}, r"progress = 'yes' is not allowed; allowed: True or False"),
])
def test_an_execution_is_checked_once_when_it_is_made(options, message):
    with pytest.raises(ValueError, match=message):
        Execution(**options)
    with pytest.raises(ValueError, match=message):
        Execution().replace(**options)


def test_a_chunk_size_moves_no_number():
    by_seed = evaluate("heuristic", "small", 3, execution=Execution(threads=1, chunk_size=1))
    at_once = evaluate("heuristic", "small", 3, execution=Execution(threads=1))
    assert by_seed.attrs["budget"]["chunks"] == 3 and at_once.attrs["budget"]["chunks"] == 1
    assert results_only(by_seed).equals(results_only(at_once))


@pytest.mark.slow
def test_the_suite_and_comparison_functions_hand_one_execution_to_every_evaluation():
    from wfbench.harness.compare import compare, compare_suite
    from wfbench.harness.suite import evaluate_suite

    run = Execution(threads=1, chunk_size=1)
    suite = evaluate_suite("heuristic", "suite-v1", [0, 1], scenarios=["small"], execution=run)
    assert suite.attrs["budget"]["small-v1"]["chunks"] == 2, "the chunk size reached the scenario's evaluation"
    table = compare(["random"], "small", [0, 1], execution=run)
    assert [df.attrs["budget"]["chunks"] for df in table.attrs["runs"].values()] == [2, 2]
    full = get_suite("suite-v1")
    one = Suite(name="suite-v1", version=1, description="small-v1 alone", scenarios=(full.scenario("small-v1"),),
                test_seeds=(0, 1))
    paired = compare_suite(["random"], one, [0, 1], poi_reps=10, execution=run)
    assert [f.attrs["budget"]["small-v1"]["chunks"] for f in paired.runs.values()] == [2, 2]
    for name, call in (("evaluate_suite", lambda: evaluate_suite("heuristic", "suite-v1", [0], backend="process")),
                       ("compare", lambda: compare(["random"], "small", [0], progress=True)),
                       ("compare_suite", lambda: compare_suite(["random"], "suite-v1", [0], workers=2))):
        with pytest.raises(TypeError, match=rf"^{name}\(\) got an unexpected keyword argument"):
            call()


@pytest.mark.slow
def test_reproduce_writes_tables_and_figure(tmp_path, capsys):
    out = tmp_path / "res"
    assert main(["reproduce", "table3", "--out", str(out), "--runs", "2", "--backend", "serial",
                 "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "| 4 | Heuristic | Heuristic | Heuristic |" in text and "higher is better" in text
    assert "46 (42-50) / 0.6 (0.5-0.8) / 0.2 (0.2-0.3) / 4.1 (3-5.1)" in text, "the paper's row 4 beside ours"
    assert "| 5 | PPO | Heuristic | Heuristic | not" not in text, "row 5 comes from the shipped ppo-dispatch"
    assert "| 6 | PPO | PPO | PPO | not" not in text, "row 6 comes from the shipped ppo-joint"
    assert "| O2 | Hindsight oracle | Hindsight oracle | Hindsight oracle |" in text and "| B | Upper bound |" in text
    df = pd.read_csv(out / "table3.csv")
    assert df["policy"].tolist()[:4] == ["random", "random-dispatch", "random-positioning", "heuristic"]
    nsw = df.set_index("policy")["nsw"]
    assert nsw["oracle"] > nsw["solver"] and nsw["bound"] > nsw.drop("bound").max(), "the bound is above every row"
    assert "| T1 | Heuristic (tuned) |" in text and "| T2 | Assignment (tuned) |" in text and "beyond the paper" in text
    assert nsw["heuristic-tuned"] > nsw["heuristic"] and nsw["solver-tuned"] > nsw["solver"]  # means over seeds 0-1
    assert df["policy"].tolist()[13:19] == ["ppo-independent", "hindsight-joint", "hindsight-ppo", "oracle-dispatch",
                                            "oracle", "bound"], "L1-L3 after the tuned rows, before the oracles"
    assert "| L3 | PPO | PPO + hindsight learning | PPO |" in text and "| L1 | PPO (own net) |" in text
    assert "not shipped yet (RL)" not in text, "every network row comes from its shipped checkpoint"
    assert nsw[["ppo-independent", "hindsight-joint", "hindsight-ppo"]].between(0.5, nsw["oracle"]).all()
    assert (out / "table3.md").read_text().startswith("Table 3")

    assert main(["reproduce", "table2", "--out", str(out), "--runs", "1", "--backend", "serial",
                 "--no-progress"]) == 0
    t2 = pd.read_csv(out / "table2.csv")
    assert len(t2) == 20 and t2["nsw"].between(0, 1).all()
    assert t2.loc[(t2.grid == 64) & (t2.facilities == 25) & (t2.personnel == 5), "paper_nsw_cost"].item() == 6.37
    assert "More personnel is better for 25 facilities" in capsys.readouterr().out

    assert main(["reproduce", "figure3", "--out", str(out), "--runs", "2", "--backend", "serial",
                 "--methods", "random,heuristic,solver", "--no-progress"]) == 0  # all: minutes (test_plots.py)
    png = (out / "figure3.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    bands = pd.read_csv(out / "figure3.csv")
    assert set(bands["kpi"]) == {"workforce_cost", "utilization", "downtime"}
    assert (bands["q25"] <= bands["q75"]).all()


def test_reproduce_bad_input(tmp_path, capsys):
    assert main(["reproduce", "table9"]) == 2
    assert "unknown target 'table9'; allowed: table2, table3, figure3, gap" in capsys.readouterr().err
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["reproduce", "table3", "--out", str(f)]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_table2_trend_counting_by_hand():
    # a world where everything the paper says holds: NSW rises with personnel, falls with facilities and grid
    nsw = {}
    for gi, g in enumerate(TABLE2_GRIDS):
        for f, s in TABLE2_CELLS:
            nsw[g, f, s] = 1.0 - 0.1 * gi + 0.01 * s - 0.001 * f
    trends = table2_trends(nsw)
    assert all(": holds here:" in t for t in trends), trends
    assert "8 of 8 pairwise comparisons, monotone in 4 of 4 grids" in trends[0]
    # flip personnel: it never holds
    flipped = {k: v - 0.02 * k[2] for k, v in nsw.items()}
    assert "does not hold here: 0 of 8" in table2_trends(flipped)[0]
    assert np.isfinite(list(nsw.values())).all()


@pytest.mark.slow
def test_reproduce_gap_draws_the_methods_and_the_bound(tmp_path):
    from wfbench.reproduce.gap import gap

    result = gap(tmp_path, runs=3, execution=Execution(), scenarios=("small", "paper-64"))
    df = pd.read_csv(tmp_path / "gap.csv")
    assert set(df["method"]) == {"heuristic", "solver", "oracle", "bound"} and set(df["scenario"]) == {"small",
                                                                                                      "paper-64"}
    for _, sc in df.groupby("scenario"):
        nsw = sc.set_index("method")["nsw"]
        assert nsw["bound"] > nsw.drop("bound").max() and nsw["oracle"] > nsw["heuristic"]
    png = (tmp_path / "gap.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 15_000
    assert (tmp_path / "gap.svg").read_text().lstrip().startswith("<?xml")
    assert "| paper-64 |" in result.text and "oracle - solver (paired, 95% CI)" in result.text


def test_reproduce_rows_name_their_decisions_from_the_policy_registry():
    from wfbench.policies.decisions import DECISIONS, LABELS
    from wfbench.policies.registry import names_of, parts

    from wfbench.reproduce.table3 import LEARNED_ROWS, ORACLE_ROWS, SOLVER_ROWS, TUNED_ROWS

    assert {d: set(t) for d, t in LABELS.items()} == {d: set(t) for d, t in DECISIONS.items()}, \
        "every built-in decision has a label for the tables (wfbench.policies.decisions.LABELS)"
    registered = [n for kind in ("composite", "oracle", "tuned", "learned", "lookahead") for n in names_of(kind)]
    for name in registered:
        assert len(parts(name)) == 3 and all(parts(name)), name
    assert parts("solver-positioning") == ("Heuristic", "Heuristic", "p-median")
    assert parts("solver-tuned") == ("Assignment (tuned)", "Staffing (tuned)", "p-median (tuned)")
    assert parts("oracle-dispatch") == ("Hindsight oracle", "Heuristic", "Heuristic")
    assert {p for rows in (SOLVER_ROWS, ORACLE_ROWS, TUNED_ROWS, LEARNED_ROWS) for _, p in rows} <= set(registered)
    with pytest.raises(ValueError, match="not a registered policy"):
        parts("nosuch")
