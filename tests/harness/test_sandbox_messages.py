"""What the sandbox says (issue #42): a SyntaxError names the package's file and line, numba's line inside the
sandbox tells where its compiled code goes, and ``wfbench evaluate --sandbox`` blames the set-up, not the policy,
when the sandbox itself cannot run."""

from __future__ import annotations

import shutil
import sys

import pytest

from wfbench.cli import main
from wfbench.harness.isolation import sandbox
from wfbench.harness.isolation.package import pack, unpack
from wfbench.harness.isolation.sandbox import SandboxError, SandboxPolicy, SandboxUnavailable

from .test_sandbox import CONTEXT, RULE, SECRET, TIGHT, _package


@pytest.mark.parametrize(("module", "entry", "shown"), [("pol.py", "pol:Policy", "pol.py"),
                                                          ("pkg/mod.py", "pkg.mod:Policy", "pkg/mod.py")])
def test_a_syntax_error_names_the_packages_file_and_line(bwrap, tmp_path, module, entry, shown):
    src = tmp_path / "src"
    (src / module).parent.mkdir(parents=True)
    if "/" in module:
        (src / "pkg" / "__init__.py").write_text("")
    (src / module).write_text("import numpy\n\nx = = 1\n")
    dest = tmp_path / "unpacked"
    unpack(pack(entry, src), dest)
    with pytest.raises(SandboxError) as info:
        SandboxPolicy(dest, entry, TIGHT, SECRET, CONTEXT)
    assert info.value.reason == f"the policy could not be loaded: SyntaxError: invalid syntax ({shown}, line 3)"


# a wfbench kernel the evaluator's cache does not hold for float32: the sandbox's numba compiles it
COLD_KERNEL = '''
import numpy as np

from wfbench.core.actions import _all_unit


class Policy:
    decisions = ("dispatch",)

    def __init__(self):
        _all_unit(np.zeros(3, dtype=np.float32))
        raise RuntimeError("compiled")

    def reset(self, keys):
        pass

    def act(self, obs):
        return {}
'''


def test_numbas_line_in_the_sandbox_does_not_promise_a_cache(bwrap, tmp_path):
    with pytest.raises(SandboxError, match="RuntimeError: compiled") as info:
        SandboxPolicy(_package(tmp_path, COLD_KERNEL), "pol:Policy", TIGHT, SECRET, CONTEXT)
    lines = [x for x in info.value.log.splitlines() if x.startswith("wfbench: compiling")]
    assert len(lines) == 1, info.value.log
    assert "cached afterwards" not in lines[0], lines[0]
    assert "thrown away with the sandbox" in lines[0] and "/tmp/numba" not in lines[0], lines[0]


def _cli(tmp_path, monkeypatch):
    (tmp_path / "mypol").mkdir()
    (tmp_path / "mypol" / "__init__.py").write_text(RULE)
    monkeypatch.chdir(tmp_path)
    return ["evaluate", "--sandbox", "--policy", "mypol:Rule", "--scenario", "small", "--seeds", "1"]


def test_cli_says_when_python_cannot_start_in_the_sandbox(bwrap, tmp_path, monkeypatch, capsys):
    argv = _cli(tmp_path, monkeypatch)
    sandbox._trial.cache_clear()
    monkeypatch.setattr(sys, "executable", "/nonexistent/venv/bin/python3")  # a Python the sandbox cannot reach
    try:
        status = main(argv)
    finally:
        sandbox._trial.cache_clear()
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: the sandbox cannot run on this machine (its "
                                                   "set-up, not the policy): Python cannot start in the sandbox"), err
    assert "/nonexistent/venv/bin/python3" in err and "the policy's process" not in err, err


def test_cli_says_when_bubblewrap_is_missing(tmp_path, monkeypatch, capsys):
    argv = _cli(tmp_path, monkeypatch)
    real = shutil.which
    monkeypatch.setattr(shutil, "which", lambda name, *a, **k: None if name == "bwrap" else real(name, *a, **k))
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("wfbench: error: the sandbox cannot run on this machine (its "
                                                   "set-up, not the policy): bubblewrap (bwrap) is not installed"), err


def test_unavailable_is_one_line():
    assert SandboxUnavailable("first line\nsecond").reason == "first line"
