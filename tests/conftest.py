import importlib.util
import os
import shutil
import sys
import tempfile
import warnings
from pathlib import Path
from types import ModuleType

import absl.logging
import numpy as np
import pytest
from hypothesis.configuration import set_hypothesis_home_dir

import wfbench
from wfbench import ScenarioConfig
from wfbench.testing import ADVISORIES

# rliable imports absl.logging, whose handler keeps the sys.stderr of the moment of its import: imported first inside
# a test (the leaderboard's ranking imports rliable lazily), it kept that test's capture, closed after it, and a later
# test whose served board logs wrote to a closed file. Imported here, it is pointed at the process's own stderr.
absl.logging.get_absl_handler().python_handler.stream = sys.__stderr__

# Hypothesis keeps its examples and the constants it read from our sources in ./.hypothesis by default, a folder in the
# checkout; tests write only to temporary folders (issue #54), so its home is one of this run's
set_hypothesis_home_dir(tempfile.mkdtemp(prefix="wfbench-hypothesis-"))

# The checkers' advice wfbench does not follow on purpose (wfbench.testing.ADVISORIES: entity features are
# (M, 7) and (N, 9) on purpose, docs/model.md). Only these are let through; any other warning in the checks fails.
KNOWN_ADVISORIES = (
    *ADVISORIES,
    wfbench.V0_CURRENT,  # Gymnasium's "out of date" for Workforce-v0 beside v1, which wfbench silences
)


@pytest.fixture
def strict_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for pattern in KNOWN_ADVISORIES:
            warnings.filterwarnings("ignore", message=pattern)
        yield


@pytest.fixture
def tiny():
    """3 personnel, 5 facilities on a 12x12 grid."""
    return ScenarioConfig(name="tiny", grid_width=12, grid_height=12, max_facilities=5, max_personnel=3,
                          initial_facilities=5, initial_personnel=3, horizon=60, request_interval=10.0,
                          window=10)


def play_episode(pol, config: ScenarioConfig, seeds,
                 scores: list | None = None) -> tuple[wfbench.Simulator, list[dict[str, np.ndarray]]]:
    """``pol`` reset and played to the end on ``seeds``: the finished simulator and a copy of each step's actions.

    ``scores``, when given, gets (step, a copy of ``pol.last_scores``) at each step a lookahead
    deliberated (its candidates' mean scores), and the attribute is cleared.
    """
    sim = wfbench.Simulator(config, seeds)
    obs = sim.reset()
    pol.reset(seeds)
    actions = []
    while not sim.done:
        a = pol.act(obs)
        actions.append({k: np.array(v, copy=True) for k, v in a.items()})
        if scores is not None and getattr(pol, "last_scores", None) is not None:
            scores.append((int(obs["t"][0]), pol.last_scores.copy()))
            pol.last_scores = None
        sim.step(a)
        obs = sim.observe()
    return sim, actions


# -- the checkout's scripts (benchmarks/, examples/): no package, so a test calling their functions loads them by path
def load_script(relative: str) -> ModuleType:
    """The script at ``relative`` from the checkout's root (``benchmarks/identity_check.py``) as a module of its name.

    Its ``if __name__ == "__main__"`` block does not run; the module is not put in ``sys.modules``.
    """
    path = Path(__file__).resolve().parents[1] / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- a real browser (the HTML leaderboard test, issue #26) ------------------------------------------------------
# Without one the test skips and says why, so the README's set-up ends green on a machine without Chromium;
# .ci/run sets WFBENCH_REQUIRE_BROWSER=1, under which a missing browser fails the test instead: CI never skips it.
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
REQUIRE_BROWSER = "WFBENCH_REQUIRE_BROWSER"


def find_browser() -> str | None:
    """The path of the first headless-capable browser on the PATH (:data:`BROWSERS`), or None."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


def browser_or_skip() -> str:
    """The browser's path; without one a skip that says why, or a failure when ``WFBENCH_REQUIRE_BROWSER=1``."""
    path = find_browser()
    if path:
        return path
    reason = (f"no headless browser on the PATH ({', '.join(BROWSERS)}): on Debian/Ubuntu "
              "`apt-get install chromium` (.ci/run installs it)")
    if os.environ.get(REQUIRE_BROWSER, "") not in ("", "0"):
        pytest.fail(f"{reason}; {REQUIRE_BROWSER}={os.environ[REQUIRE_BROWSER]} requires it", pytrace=False)
    pytest.skip(reason)


def pytest_configure(config):
    # the oracle's totals cache (wfbench.policies.oracle.cache) goes to a folder of this run, never the user's
    # cache: a test that counts plays must not find an earlier run's totals (subprocesses inherit the variable)
    if not os.environ.get("WFBENCH_ORACLE_CACHE"):
        import tempfile

        os.environ["WFBENCH_ORACLE_CACHE"] = config._wfbench_oracle_cache = tempfile.mkdtemp(
            prefix="wfbench-oracle-totals-")
    config.addinivalue_line("markers", "needs_browser: the test opens a page in a headless browser; it skips with "
                                       f"its reason without one, and fails instead under {REQUIRE_BROWSER}=1")


def pytest_unconfigure(config):
    made = getattr(config, "_wfbench_oracle_cache", None)  # only the process that made it (xdist's workers inherit)
    if made:
        shutil.rmtree(made, ignore_errors=True)


def pytest_runtest_setup(item):
    if item.get_closest_marker("needs_browser") is not None:
        browser_or_skip()


@pytest.fixture
def browser() -> str:
    """The path of a headless browser (see :func:`browser_or_skip`)."""
    return browser_or_skip()


# -- the hosted leaderboard's services (issue #34): a PostgreSQL server and bubblewrap ---------------------------
# Like the browser: without one the tests that need it skip and say why; .ci/run installs both and sets
# WFBENCH_REQUIRE_POSTGRES=1 and WFBENCH_REQUIRE_BWRAP=1, under which a missing one fails those tests instead.
POSTGRES_URL = "WFBENCH_TEST_POSTGRES_URL"
REQUIRE_POSTGRES = "WFBENCH_REQUIRE_POSTGRES"
REQUIRE_BWRAP = "WFBENCH_REQUIRE_BWRAP"


def _skip_or_fail(reason: str, require: str) -> None:
    if os.environ.get(require, "") not in ("", "0"):
        pytest.fail(f"{reason}; {require}={os.environ[require]} requires it", pytrace=False)
    pytest.skip(reason)


@pytest.fixture
def postgres_url():
    """The URL of a fresh, empty PostgreSQL database for this test, dropped after it.

    The server is the one ``$WFBENCH_TEST_POSTGRES_URL`` names (a ``postgresql+psycopg://`` URL whose role may
    create databases; .ci/run starts Debian's cluster and sets it). Each test gets its own database, so tests
    run side by side under xdist.
    """
    import uuid

    import sqlalchemy as sa

    base = os.environ.get(POSTGRES_URL, "")
    if not base:
        _skip_or_fail(f"no PostgreSQL server: set {POSTGRES_URL}=postgresql+psycopg://USER:PASSWORD@127.0.0.1/DB "
                      "(a role that may CREATE DATABASE; .ci/run starts Debian's postgresql and sets it)",
                      REQUIRE_POSTGRES)
    url = sa.engine.make_url(base)
    name = f"wfbench_test_{uuid.uuid4().hex[:12]}"
    admin = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
    except sa.exc.OperationalError as e:
        admin.dispose()
        _skip_or_fail(f"the PostgreSQL server at {url.render_as_string(hide_password=True)} does not answer: "
                      f"{str(e).splitlines()[0]}", REQUIRE_POSTGRES)
    try:
        yield url.set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


@pytest.fixture
def bwrap() -> str:
    """The path of bubblewrap, which runs submitted policies (:mod:`wfbench.harness.isolation.sandbox`)."""
    path = shutil.which("bwrap")
    if not path:
        _skip_or_fail("bubblewrap is not installed: on Debian/Ubuntu `apt-get install bubblewrap` "
                      "(.ci/run installs it)", REQUIRE_BWRAP)
    from wfbench.harness.isolation.sandbox import SandboxUnavailable, _seccomp_program

    try:  # the sandbox's seccomp filter needs libseccomp's Python bindings (issue #42)
        _seccomp_program()
    except SandboxUnavailable as exc:
        _skip_or_fail(f"{exc} (.ci/run installs them)", REQUIRE_BWRAP)
    return path


@pytest.fixture
def oracle_totals(tmp_path, monkeypatch):
    """The oracle's totals cache on, in a private, empty folder (and an empty memory) for one test: the folder."""
    from wfbench.policies.oracle import cache

    monkeypatch.setenv(cache.ENV, str(tmp_path / "totals"))
    cache.clear_memory()
    yield tmp_path / "totals"
    cache.clear_memory()
