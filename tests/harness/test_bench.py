"""``wfbench bench`` reports what it measured; speed itself is never asserted (docs/performance.md)."""

import json

import numba
import pytest

from wfbench.harness.bench import run


@pytest.mark.slow
def test_rounds_are_interleaved_and_summarized(tmp_path, capsys):
    out = tmp_path / "bench.json"
    rows = run("small", quick=True, json_path=str(out), rounds=2)
    data = json.loads(out.read_text())
    assert data["rounds"] == 2 and data["results"] == rows
    names = [r["measurement"] for r in rows]
    assert any("PettingZoo" in n for n in names) and any("B=1, 1 thread" in n for n in names)
    # step_observe by thread count: one thread, and all of numba's when there are more
    assert "Simulator.step_observe, random actions, B=64, 1 thread" in names
    cores = numba.config.NUMBA_NUM_THREADS
    assert (f"Simulator.step_observe, random actions, B=64, {cores} threads" in names) == (cores > 1)
    for r in rows:
        assert len(r["rounds"]) == 2 and all(v > 0 for v in r["rounds"])
        assert r["env_steps_per_s"] == max(r["rounds"]) and r["worst"] == min(r["rounds"])
        assert r["worst"] <= r["median"] <= r["env_steps_per_s"]
    assert [ref["when"] for ref in data["reference"]] == ["before", "after"]
    assert all(ref["python_loop_s"] > 0 and ref["compiled_loop_s"] > 0 for ref in data["reference"])
    printed = capsys.readouterr().out
    # every round prints every row, in the same order, before the summary
    first, second = printed.split("round 2 of 2")
    assert [n for n in names if n in first] == names and [n for n in names if n in second] == names
    assert "best" in second and "median" in second and "worst" in second
