"""``wfbench reproduce`` is a shell over wfbench.reproduce.reproduce: the same files, the same refusals."""

from __future__ import annotations

import pandas as pd
import pytest

from wfbench.cli import main
from wfbench.harness.backends import Execution
from wfbench.reproduce import output_folder, parse_methods, reproduce


def test_the_command_and_the_function_write_the_same_files(tmp_path, capsys):
    api = reproduce("figure3", tmp_path / "api" / "deep", runs=1, execution=Execution(), methods="random, random")
    assert main(["reproduce", "figure3", "--methods", "random,random", "--runs", "1", "--backend", "serial",
                 "--out", str(tmp_path / "cli" / "deep"), "--no-progress"]) == 0
    assert api.text in capsys.readouterr().out
    names = sorted(p.name for p in (tmp_path / "api" / "deep").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "cli" / "deep").iterdir()) == sorted(f.name for f in api.files)
    a, c = tmp_path / "api" / "deep", tmp_path / "cli" / "deep"
    pd.testing.assert_frame_equal(pd.read_csv(a / "figure3.csv"), pd.read_csv(c / "figure3.csv"))
    assert (a / "figure3.md").read_text() == (c / "figure3.md").read_text()


@pytest.mark.parametrize("target, methods, why", [
    ("table2", "random", "applies to figure3 only, not to table2"),
    ("figure3", " , ", "give at least one policy name"),
    ("figure3", "random,nope", "unknown policy 'nope'"),
])
def test_methods_are_refused_alike(target, methods, why, tmp_path, capsys):
    with pytest.raises(ValueError, match=why) as api:
        parse_methods(methods, target)
    with pytest.raises(ValueError, match=why):
        reproduce(target, tmp_path / "r", methods=methods)
    assert main(["reproduce", target, "--methods", methods, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    said = str(api.value) if "nope" in why else str(api.value).replace("methods", "--methods", 1)
    assert err == f"wfbench: error: {said}\n"
    assert not (tmp_path / "r").exists(), "refused before the folder is made"


def test_an_output_path_that_is_a_file_is_refused_alike(tmp_path, capsys):
    file = tmp_path / "taken"
    file.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a folder") as api:
        reproduce("table3", file, runs=1, execution=Execution())
    assert main(["reproduce", "table3", "--out", str(file), "--runs", "1", "--backend", "serial"]) == 2
    assert capsys.readouterr().err == f"wfbench: error: --{api.value}\n"
    with pytest.raises(ValueError, match="cannot create the folder"):
        output_folder(file / "below")
    assert output_folder(tmp_path / "a" / "b").is_dir()
