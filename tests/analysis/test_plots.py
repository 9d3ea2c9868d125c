"""Every result as a picture: compare --plot, the fuller figure3, table2's trends per KPI (issue 17)."""

from __future__ import annotations

import importlib.util

import pandas as pd
import pytest
from wfbench.policies.registry import learned_names, names_of

from wfbench.analysis.plots import figure_format
from wfbench.cli import main
from wfbench.core.kpis import kpi_score
from wfbench.core.presets import TABLE2_CELLS, TABLE2_GRIDS
from wfbench.harness.backends import Execution
from wfbench.harness.compare import compare, plot_comparison
from wfbench.reproduce.figure3 import FIGURE3_METHODS, figure3, figure3_methods
from wfbench.reproduce.table2 import TREND_KPIS, table2, table2_trend_counts, table2_trends_per_kpi

PNG = b"\x89PNG\r\n\x1a\n"


def _is_png(path, min_bytes=10_000) -> bool:
    data = path.read_bytes()
    return data[:8] == PNG and len(data) > min_bytes


def _svg(path, min_bytes=10_000) -> str:
    text = path.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text and len(text) > min_bytes
    return text


@pytest.fixture(scope="module")
def small_comparison():
    return compare(["heuristic", "random", "solver"], "small", 4)


@pytest.mark.slow
def test_compare_plot_writes_every_format(small_comparison, tmp_path):
    df = small_comparison
    plot_comparison(df, tmp_path / "c.png")
    plot_comparison(df, tmp_path / "c.svg")
    fig = plot_comparison(df, tmp_path / "c.pdf")
    assert _is_png(tmp_path / "c.png", 30_000)
    svg = _svg(tmp_path / "c.svg")
    for name in ("heuristic", "random", "solver", "NSW - heuristic, paired by seed", "Facility downtime"):
        assert name in svg, name
    # the intervals drawn are the table's, printed beside each policy
    r = df.set_index("policy").loc["random"]
    assert f"{r['nsw_diff']:+.4f} [{r['nsw_diff_low']:+.4f}, {r['nsw_diff_high']:+.4f}]" in svg
    assert (tmp_path / "c.pdf").read_bytes()[:5] == b"%PDF-"
    assert len(fig.axes) == 5  # four KPI panels and the paired differences
    # a frame without per-seed runs (e.g. read back from CSV) still draws, from the summary columns
    plain = pd.DataFrame(df.to_dict("list"))
    plain.attrs = {"baseline": "heuristic"}
    plot_comparison(plain, tmp_path / "plain.png")
    assert _is_png(tmp_path / "plain.png")


def test_compare_plot_argument_checks_the_suffix_first(tmp_path):
    with pytest.raises(ValueError, match=r"suffix '\.jpg'; allowed: \.png, \.svg, \.pdf"):
        compare(["random"], "small", 1, plot=tmp_path / "c.jpg")
    with pytest.raises(ValueError, match="has no suffix"):
        figure_format(tmp_path / "c")
    assert figure_format("a/B.SVG") == "svg"
    df = compare(["random"], "small", 2, plot=tmp_path / "c.svg")
    assert "random" in _svg(tmp_path / "c.svg") and len(df) == 2


def test_compare_cli_plot(tmp_path, capsys):
    out = tmp_path / "cmp.png"
    assert main(["compare", "--policies", "heuristic,random", "--scenario", "small", "--seeds", "3",
                 "--backend", "serial", "--no-progress", "--format", "csv", "--plot", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("policy,") and f"wrote {out}" in captured.err  # stdout stays a clean CSV
    assert _is_png(out, 30_000)


@pytest.mark.parametrize("plot, message", [
    ("out.jpg", "--plot: figure 'out.jpg' has suffix '.jpg'; allowed: .png, .svg, .pdf"),
    ("out", "has no suffix"),
    ("missing/out.png", "--plot 'missing/out.png': folder 'missing' does not exist"),
    ("folder.png", "--plot 'folder.png' is a folder; give a file name"),
])
def test_compare_cli_plot_errors_are_one_line(plot, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder.png").mkdir()
    assert main(["compare", "--policies", "random", "--scenario", "small", "--seeds", "2", "--backend",
                 "serial", "--no-progress", "--plot", plot]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: ") and message in err, err


def test_compare_cli_plot_write_failure_is_one_line(tmp_path, capsys):
    assert main(["compare", "--policies", "random", "--baseline", "random", "--scenario", "small", "--seeds", "1",
                 "--backend", "serial", "--no-progress", "--plot", "/proc/wfbench-cannot-write.png"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: --plot: cannot write '/proc/wfbench-cannot-write.png'"), err
    assert err.count("\n") == 1


def _trend_counts_by_hand(v: dict, kpi: str, target: float) -> dict[str, tuple[int, int, int]]:
    """The paper's three trends counted pair by pair (held, total, tied), apart from the chains of table2.py."""
    def compare(b, a):  # +1: cell b is better than cell a in this KPI, 0: a tie, -1: worse
        x, y = (v[b], v[a]) if kpi == "nsw" else (-abs(v[b] - target), -abs(v[a] - target)) \
            if kpi == "utilization" else (-v[b], -v[a])
        return (x > y) - (x < y)

    pairs = {
        "personnel": [((g, 25, 10), (g, 25, 5)) for g in TABLE2_GRIDS] + [((g, 25, 25), (g, 25, 10))
                                                                           for g in TABLE2_GRIDS],
        "facilities": [((g, 25, 25), (g, 50, 25)) for g in TABLE2_GRIDS] + [((g, 50, 25), (g, 100, 25))
                                                                             for g in TABLE2_GRIDS],
        "grid": [((small, f, s), (large, f, s)) for f, s in TABLE2_CELLS
                 for small, large in zip(TABLE2_GRIDS, TABLE2_GRIDS[1:], strict=False)],
    }
    out = {}
    for trend, ps in pairs.items():
        c = [compare(b, a) for b, a in ps]
        out[trend] = (c.count(1), len(c), c.count(0))
    return out


def test_table2_reports_the_trends_per_kpi(tmp_path):
    """One run per cell (cheap); the counts are checked against a count by hand of the same means."""
    result = table2(tmp_path, runs=1, execution=Execution())
    cells = pd.read_csv(tmp_path / "table2.csv")
    counts = pd.read_csv(tmp_path / "table2_trends.csv")
    assert set(counts["kpi"]) == set(TREND_KPIS) and len(counts) == 3 * len(TREND_KPIS)
    for kpi in TREND_KPIS:
        v = {(r.grid, r.facilities, r.personnel): getattr(r, kpi) for r in cells.itertuples()}
        expected = _trend_counts_by_hand(v, kpi, 0.75)
        got = counts[counts["kpi"] == kpi].set_index("trend")
        for trend, (held, total, tied) in expected.items():
            assert tuple(got.loc[trend, ["held", "total", "ties"]]) == (held, total, tied), (kpi, trend)
            assert f"{held}/{total}{f', {tied} tied' if tied else ''} (monotone in" in result.text
    # a fixed workforce costs the same on every grid and with any number of facilities: ties, not broken trends
    assert tuple(counts.set_index(["kpi", "trend"]).loc[("workforce_cost", "grid"), ["held", "ties"]]) == (0, 15)
    assert "| Facility downtime (lower) |" in result.text and "| Nash social welfare (higher) |" in result.text
    assert "More personnel is better for 25 facilities (5S < 10S < 25S): holds" in result.text  # NSW sentences
    assert _is_png(tmp_path / "table2.png", 30_000)
    svg = _svg(tmp_path / "table2.svg")
    assert "Facility downtime" in svg and "256 x 256" in svg


def test_trend_counts_per_kpi_on_a_made_up_world():
    # downtime falls with personnel and rises with facilities and grid everywhere: every downtime trend holds;
    # utilization falls with personnel from above the target, so more personnel moves it toward 0.75
    down = {(g, f, s): 0.1 * i + 0.001 * f - 0.002 * s for i, g in enumerate(TABLE2_GRIDS) for f, s in TABLE2_CELLS}
    util = {(g, f, s): 1.0 - 0.005 * s for g in TABLE2_GRIDS for f, s in TABLE2_CELLS}
    per_kpi = table2_trends_per_kpi({"downtime": down, "utilization": util})
    assert [(t.held, t.total, t.monotone, t.chains) for t in per_kpi["downtime"]] == [(8, 8, 4, 4), (8, 8, 4, 4),
                                                                                     (15, 15, 5, 5)]
    assert per_kpi["utilization"][0].held == 8 and per_kpi["utilization"][2].held == 0  # grid: ties never hold
    assert per_kpi["downtime"][2].cell() == "15/15 (monotone in 5/5 columns)"
    assert table2_trend_counts(down)[0].held == 0  # the same values read as higher-is-better: all broken
    assert kpi_score("utilization", 0.7) == kpi_score("utilization", 0.8) < kpi_score("utilization", 0.75)
    with pytest.raises(ValueError, match="unknown KPI 'speed'"):
        kpi_score("speed", 1.0)


@pytest.mark.slow
def test_figure3_draws_every_kind_of_method(tmp_path):
    methods = figure3_methods()
    for m in ("random", "heuristic", "solver", "heuristic-tuned", "solver-tuned", "oracle-dispatch", "oracle"):
        assert m in methods
    if importlib.util.find_spec("torch") is not None:
        assert set(learned_names()) <= set(methods) and set(learned_names()) <= set(names_of("learned"))
    assert methods == tuple(m for m in FIGURE3_METHODS if m in methods), "in the groups' order"
    # cheap: one method of three groups, two episodes (the learned ones: docs/reproduction.md's full run)
    result = figure3(tmp_path, runs=2, execution=Execution(), methods=("random", "heuristic-tuned", "oracle-dispatch"))
    assert _is_png(tmp_path / "figure3.png", 40_000)
    svg = _svg(tmp_path / "figure3.svg")
    for text in ("random", "heuristic-tuned", "oracle-dispatch", "Solvers and tuned", "Hindsight oracles",
                 "heuristic (median)"):
        assert text in svg, text
    bands = pd.read_csv(tmp_path / "figure3.csv")
    assert set(bands["method"]) == {"random", "heuristic-tuned", "oracle-dispatch"}  # the reference is not a row
    assert any(str(p).endswith("figure3.svg") for p in result.files)


def test_reproduce_methods_errors_are_one_line(tmp_path, capsys):
    for argv, message in (
        (["reproduce", "table2", "--methods", "heuristic"], "--methods applies to figure3 only, not to table2"),
        (["reproduce", "figure3", "--methods", " , "], "--methods: give at least one policy name"),
        (["reproduce", "figure3", "--methods", "heuristic,nosuch"], "nosuch"),
    ):
        assert main([*argv, "--out", str(tmp_path / "r"), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("wfbench: error: ") and message in err, err
    assert not (tmp_path / "r" / "figure3.png").exists()
