"""benchmarks/identity_check.py compare: a moved number is a difference; a field only the newer code records is not."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import load_script

torch = pytest.importorskip("torch")


@pytest.fixture(scope="module")
def check():
    return load_script("benchmarks/identity_check.py")


def _capture(root: Path, weight: float, history: list[dict], settings: dict) -> Path:
    run = root / "train-ppo-joint"
    run.mkdir(parents=True)
    torch.save({"model": {"w": torch.tensor([1.0, weight])}, "history": history}, run / "latest.pt.model")
    (run / "config.clean.json").write_text(json.dumps(settings))
    return root


BEFORE = ([{"update": 1, "mean_nsw": 0.61}], {"seed": 0, "lr": 3e-4})


def test_a_field_only_the_second_capture_records_is_listed_apart_not_a_difference(check, tmp_path, capsys):
    a = _capture(tmp_path / "a", 2.0, *BEFORE)
    b = _capture(tmp_path / "b", 2.0, [{"update": 1, "mean_nsw": 0.61, "select": "sample"}],
                 {"seed": 0, "lr": 3e-4, "shards": 1})
    assert check.compare(a, b) == 0
    out = capsys.readouterr().out
    assert "history records ['select'] too" in out and "settings ['shards'] too" in out
    assert "2 files compared, 0 differences, 2 with fields only the second records" in out


@pytest.mark.parametrize("weight, history, settings, says", [
    (2.5, *BEFORE, "latest.pt.model: weights differ"),
    (2.0, [{"update": 1, "mean_nsw": 0.62, "select": "sample"}], BEFORE[1], "latest.pt.model: history differs"),
    (2.0, BEFORE[0], {"seed": 0, "lr": 1e-3}, "config.clean.json: keys differ: ['lr']"),
    (2.0, BEFORE[0], {"seed": 0}, "config.clean.json: keys differ: ['lr']"),
], ids=["weights", "a recorded value", "a setting", "a setting gone"])
def test_a_moved_value_is_a_difference(check, tmp_path, capsys, weight, history, settings, says):
    a = _capture(tmp_path / "a", 2.0, *BEFORE)
    b = _capture(tmp_path / "b", weight, history, settings)
    assert check.compare(a, b) == 1
    assert says in capsys.readouterr().out
