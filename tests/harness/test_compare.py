"""Paired comparison of policies on common seeds, and its command."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from wfbench.analysis.stats import bootstrap_ci, paired_difference
from wfbench.cli import main
from wfbench.harness.compare import compare, compare_suite, format_comparison, format_suite_comparison, plot_comparison
from wfbench.harness.evaluation import evaluate


def test_compare_pairs_by_seed():
    seeds = [0, 1, 2, 3]
    df = compare(["random-dispatch", "random"], "small", seeds, baseline="heuristic")
    assert df["policy"].tolist() == ["heuristic", "random-dispatch", "random"] and df.attrs["baseline_added"]
    base = df.set_index("policy")
    assert base.loc["heuristic", "nsw_diff"] == 0.0
    h = evaluate("heuristic", "small", seeds)["nsw"].to_numpy()
    r = evaluate("random", "small", seeds)["nsw"].to_numpy()
    assert base.loc["random", "nsw_diff"] == pytest.approx((r - h).mean())
    assert base.loc["random", "nsw_diff_low"] <= base.loc["random", "nsw_diff"] <= base.loc["random", "nsw_diff_high"]
    assert base.loc["random", "wins"] == int((r > h).sum())
    text = format_comparison(df, "md")
    assert text.count("\n") == 4 and "(baseline)" in text


def test_bootstrap_intervals():
    ci = bootstrap_ci(np.arange(20.0))
    assert ci.low < 9.5 < ci.high and ci.estimate == 9.5
    assert bootstrap_ci([0.3, 0.3, 0.3]) == (0.3, 0.3, 0.3)
    assert bootstrap_ci(np.arange(20.0)) == ci, "fixed generator: the same interval every time"
    d = paired_difference([1.0, 2.0, 3.0, 4.0], [0.0, 1.0, 2.0, 3.5])
    assert d.estimate == pytest.approx(0.875) and d.low >= 0.5 and d.high <= 1.0
    with pytest.raises(ValueError, match="one value per common seed"):
        paired_difference([1.0, 2.0], [1.0])


@pytest.mark.slow
def test_compare_command_and_its_errors(capsys):
    assert main(["compare", "--policies", "solver", "--scenario", "small", "--seeds", "3", "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert "solver" in captured.out and "heuristic" in captured.out and "paired" in captured.out
    assert captured.err == ("wfbench: note: the baseline 'heuristic' is not in --policies; added it as the first row "
                            "(choose another with --baseline)\n")
    assert main(["compare", "--policies", "random,heuristic", "--scenario", "small", "--seeds", "2", "--format",
                 "csv", "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "", "no note when the baseline is listed"
    assert [line.split(",")[0] for line in captured.out.splitlines()[1:]] == ["random", "heuristic"]
    assert main(["compare", "--policies", "solver,nope", "--scenario", "small", "--seeds", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown policy 'nope'" in err
    assert main(["compare", "--policies", ",", "--scenario", "small"]) == 2


@pytest.mark.parametrize("plot, why", [("fig.gif", "has suffix '.gif'"), ("nowhere/fig.png", "does not exist"),
                                       ("folder.png", "is a folder; give a file name")])
def test_compare_refuses_a_plot_path_before_running_as_the_command_does(plot, why, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder.png").mkdir()
    ran = []
    monkeypatch.setattr("wfbench.harness.compare.evaluate", lambda *a, **k: ran.append(a))
    with pytest.raises(ValueError) as api:
        compare(["random"], "small", [0], plot=plot)
    assert ran == [], "refused before any policy ran"
    assert main(["compare", "--policies", "random", "--scenario", "small", "--seeds", "1", "--plot", plot]) == 2
    assert ran == []
    err = capsys.readouterr().err
    assert why in str(api.value) and err == f"wfbench: error: {str(api.value).replace('plot', '--plot', 1)}\n"
    with pytest.raises(ValueError, match=why):
        plot_comparison(pd.DataFrame(), plot)


@pytest.mark.slow
def test_suite_comparison_table_is_the_api_s(monkeypatch, capsys):
    from tests.scenarios.test_suite import _mini

    result = compare_suite(["random"], _mini(), [0, 1], baseline="heuristic", poi_reps=10)
    table = format_suite_comparison(result, "md")
    assert table.splitlines()[0].split("|")[1:-1] == [" Scenario ", " Split ", " Policy ", " NSW ", " Normalized ",
                                                      " - heuristic (paired, 95% CI) ", " wins / 2 "]
    rows = [line.split("|")[1:-1] for line in table.splitlines()[2:]]
    assert [(r[0].strip(), r[2].strip()) for r in rows] == [(sc, p) for sc in ("small-v1", "large-v1")
                                                            for p in ("heuristic", "random")]
    assert [r[5].strip() for r in rows[::2]] == ["(baseline)", "(baseline)"]
    monkeypatch.setattr("wfbench.harness.compare.compare_suite", lambda *a, **k: result)
    for fmt in ("md", "csv"):
        assert main(["compare", "--policies", "random", "--suite", "suite-v1", "--seeds", "2", "--format", fmt]) == 0
        out = capsys.readouterr().out
        text = format_suite_comparison(result, fmt)
        assert out.startswith(text) and (fmt != "csv" or out == text)
