"""A first hour that ends green (issue #26): what the README's two set-up commands promise.

- The HTML leaderboard test needs a real browser: without one it skips and says why (so
  the set-up ends green on a machine without Chromium), and under
  ``WFBENCH_REQUIRE_BROWSER=1``, which ``.ci/run`` sets, it fails instead, so CI never
  skips it (``tests/conftest.py``: the ``needs_browser`` marker and the ``browser`` fixture).
- The README's commands run as written after the set-up (no bare ``wfbench``).
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REQUIRE_BROWSER, browser_or_skip, find_browser

ROOT = Path(__file__).resolve().parents[2]
CONFTEST = ROOT / "tests" / "conftest.py"


def _no_browser(monkeypatch, tmp_path):
    """A PATH with no browser on it (an empty folder): what a fresh machine without Chromium has."""
    monkeypatch.setenv("PATH", str(tmp_path))
    assert find_browser() is None


def test_browser__missing_browser_skips_with_its_reason(monkeypatch, tmp_path):
    _no_browser(monkeypatch, tmp_path)
    monkeypatch.delenv(REQUIRE_BROWSER, raising=False)
    with pytest.raises(pytest.skip.Exception, match=r"no headless browser on the PATH .*apt-get install chromium"):
        browser_or_skip()
    monkeypatch.setenv(REQUIRE_BROWSER, "0")  # 0 is "not required", as unset
    with pytest.raises(pytest.skip.Exception):
        browser_or_skip()


def test_browser__missing_browser_fails_when_required(monkeypatch, tmp_path):
    _no_browser(monkeypatch, tmp_path)
    monkeypatch.setenv(REQUIRE_BROWSER, "1")
    with pytest.raises(pytest.fail.Exception, match=r"apt-get install chromium.*WFBENCH_REQUIRE_BROWSER=1 requires it"):
        browser_or_skip()


def test_browser__a_browser_on_the_path_is_found(monkeypatch, tmp_path):
    fake = tmp_path / "chromium-browser"
    fake.write_text("#!/bin/sh\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setenv(REQUIRE_BROWSER, "1")
    assert browser_or_skip() == str(fake)


def _inner_session(tmp_path, env_extra):
    """A pytest run of one ``needs_browser`` test and one ``browser``-fixture test, with no browser on the PATH."""
    (tmp_path / "conftest.py").write_text(CONFTEST.read_text())
    (tmp_path / "test_page.py").write_text(
        "import pytest\n\n\n"
        "@pytest.mark.needs_browser\n"
        "def test_marked():\n    pass\n\n\n"
        "def test_fixture(browser):\n    pass\n"
    )
    empty = tmp_path / "bin"
    empty.mkdir()
    env = {k: v for k, v in os.environ.items() if k != REQUIRE_BROWSER}
    env |= {"PATH": str(empty), "PYTHONPATH": str(ROOT), **env_extra}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-rsf", "-p", "no:cacheprovider", "test_page.py"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_browser__a_session_without_a_browser_reports_skips_with_the_reason(tmp_path):
    out = _inner_session(tmp_path, {})
    assert out.returncode == 0, out.stdout + out.stderr
    assert "2 skipped" in out.stdout, out.stdout
    assert out.stdout.count("no headless browser on the PATH") == 2, out.stdout  # -rs shows each reason


@pytest.mark.slow
def test_browser__a_session_that_requires_a_browser_fails_in_one_line(tmp_path):
    out = _inner_session(tmp_path, {REQUIRE_BROWSER: "1"})
    assert out.returncode == 1, out.stdout + out.stderr
    assert re.search(r"2 (failed|errors?)|1 failed, 1 error", out.stdout), out.stdout
    assert "WFBENCH_REQUIRE_BROWSER=1 requires it" in out.stdout
    assert "Traceback" not in out.stdout and "def browser_or_skip" not in out.stdout  # the reason, not our code


def test_browser__ci_requires_the_browser_before_running_the_tests():
    ci = (ROOT / ".ci" / "run").read_text()
    export = ci.find(f"export {REQUIRE_BROWSER}=1")
    assert export != -1, f".ci/run must export {REQUIRE_BROWSER}=1 so that CI never skips the browser test"
    assert export < ci.find(".venv/bin/pytest"), "the variable must be set before the tests run"


def _bash_blocks(text: str) -> list[str]:
    return re.findall(r"```bash\n(.*?)```", text, re.DOTALL)


def test_readme__starts_with_the_two_set_up_commands_that_ci_runs():
    readme = (ROOT / "README.md").read_text()
    first = _bash_blocks(readme)[0].strip().splitlines()
    assert len(first) == 2 and "pip install" in first[0] and first[1].startswith(".venv/bin/pytest"), first
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    for command in first:
        assert command in ci, f".ci/run does not run the README's set-up command {command!r}"


def test_readme__commands_run_after_the_set_up_without_activating_the_venv():
    """Right after the set-up ``wfbench`` is not on the PATH: every command names ``.venv/bin/wfbench``."""
    readme = (ROOT / "README.md").read_text()
    bare = [line for block in _bash_blocks(readme) for line in block.splitlines()
            if re.search(r"(^|[;&|]\s*)wfbench\b", line.split("#")[0].strip())]
    assert not bare, f"README.md calls a bare wfbench (not on the PATH after the set-up): {bare}"
    elided = [line for block in _bash_blocks(readme) for line in block.splitlines()
              if "..." in line.split("#")[0].split()]
    assert not elided, f"README.md shows commands with elided arguments, which do not run as written: {elided}"
