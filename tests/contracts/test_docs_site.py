"""The documentation site builds strict, and its API reference covers the public API.

`mkdocs build --strict` (mkdocs.yml at the root) fails on a broken link or anchor, a
page missing from the nav, a reference that does not resolve, or a docstring the
Google-style parser cannot read. mkdocs comes with the `docs` extra, which `dev` pulls
in: if it is missing this test fails rather than skips, since CI installs `.[dev]`.
"""

import importlib
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
API_PAGES = ("wfbench", "simulator", "envs", "policies", "oracles", "solvers", "leaderboard", "reproduce")

# Names without an __all__ that a reader looks up first, by the page that must have them.
KEY_NAMES = {
    "simulator": ["wfbench.core.simulator.Simulator", "wfbench.core.simulator.Simulator.step",
                  "wfbench.core.actions.ActionError", "wfbench.core.kpis.KPIS", "wfbench.core.reward.step_reward"],
    "reproduce": ["wfbench.reproduce.table2.table2", "wfbench.reproduce.table3.table3",
                  "wfbench.reproduce.figure3.figure3", "wfbench.reproduce.gap.gap"],
    "wfbench": ["wfbench.harness.evaluation.evaluate", "wfbench.harness.compare.compare",
                "wfbench.core.config.ScenarioConfig",
                "wfbench.core.layout.FacilityLayout", "wfbench.scenarios.importer.from_files"],
    "envs": ["wfbench.envs.gym_env.WorkforceEnv", "wfbench.envs.gym_env.DispatchEnv",
             "wfbench.envs.parallel.WorkforceParallelEnv", "wfbench.envs.vector.WorkforceVectorEnv",
             "wfbench.envs.sb3.WorkforceVecEnv"],
    "policies": ["wfbench.policies.protocol.Policy", "wfbench.policies.protocol.Policy.act",
                 "wfbench.policies.protocol.Policy.reset",
                 "wfbench.policies.registry.get", "wfbench.policies.composite.Composite"],
    "oracles": ["wfbench.core.fork.fork", "wfbench.core.bound.score_upper_bound",
                "wfbench.policies.oracle.planner.Planner"],
    "solvers": ["wfbench.solvers.assignment.solve", "wfbench.solvers.facility_location.solve_p_median",
                "wfbench.solvers.staffing.square_root_staffing", "wfbench.solvers.result.SolveResult"],
    "leaderboard": ["wfbench.leaderboard.tracks.Track", "wfbench.leaderboard.submit.submit",
                    "wfbench.leaderboard.store.Store",
                    "wfbench.leaderboard.report.ranking"],
}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    assert importlib.util.find_spec("mkdocs") is not None, (
        "mkdocs is not installed: `.venv/bin/pip install -e '.[docs]'` (the dev extra includes it)"
    )
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (
        "`mkdocs build --strict` failed; fix the link, nav entry or docstring it names "
        f"(mkdocs.yml, docs/).\n--- output ---\n{(proc.stdout + proc.stderr)[-6000:]}"
    )
    return out


def anchors(site: Path, page: str) -> set[str]:
    html = (site / "api" / page / "index.html").read_text()
    return set(re.findall(r'id="([A-Za-z_][\w.]*)"', html))


@pytest.mark.slow
def test_site_builds_strict_with_every_page(site):
    for md in (ROOT / "docs").rglob("*.md"):
        built = site / md.relative_to(ROOT / "docs").with_suffix("")
        built = built.parent / "index.html" if built.name == "index" else built / "index.html"
        assert built.is_file(), f"docs/{md.relative_to(ROOT / 'docs')} did not become a page of the site"
    assert (site / "search" / "search_index.json").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("page", sorted(KEY_NAMES))
def test_api_page_has_key_names(site, page):
    missing = [name for name in KEY_NAMES[page] if name not in anchors(site, page)]
    assert not missing, f"docs/api/{page}.md renders no entry for {missing}; add a `::: name` directive"


@pytest.mark.slow
@pytest.mark.parametrize("package", ["wfbench", "wfbench.envs", "wfbench.policies", "wfbench.solvers",
                                     "wfbench.testing", "wfbench.scenarios"])
def test_api_reference_covers_all(site, package):
    """Every name a package exports in __all__ has an entry somewhere in the API reference."""
    every = set().union(*(anchors(site, page) for page in API_PAGES))
    exported = [n for n in importlib.import_module(package).__all__ if not n.startswith("_")]
    missing = [n for n in exported if not any(a == n or a.endswith("." + n) for a in every)]
    assert not missing, f"{package}.__all__ names {missing}, which docs/api/*.md do not document"
