"""The KPIs and the rewards are defined once (wfbench/core/kpis.py, wfbench/core/reward.py) and read everywhere.

A second hand-written list of the KPIs, or a second copy of a reward formula, is a bug
waiting to drift: these tests read every module of ours and fail on one, naming the file
and line. The fix is to import the name from ``wfbench.core.kpis`` or call
``wfbench.core.reward.step_reward``.
"""

import ast
from pathlib import Path

import numpy as np
import pytest

from wfbench.core.kpis import BY_NAME, KPI_NAMES, KPIS, MEASURED, METRICS, SCORE, UTILITIES, kpi_score
from wfbench.core.reward import REWARDS, step_reward
from wfbench.scenarios.resolve import resolve_scenario

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("wfbench", "policies", "leaderboard", "solvers")
TABLE = ROOT / "wfbench" / "core" / "kpis.py"
REVISIONS = ROOT / "leaderboard" / "board" / "migrations" / "versions"  # the board's Alembic revisions
# where the utility columns may be named: defined (state), computed (dynamics), made a reward (reward)
REWARD_HOMES = {ROOT / "wfbench" / "core" / name for name in ("reward.py", "dynamics.py", "state.py")}
# a fork rebuilds the state's metrics row of the step it starts from out of the observed KPIs (the utilities are
# inverted from them, not a reward computed again): the one module besides the homes that writes those columns
STATE_REBUILDERS = {ROOT / "wfbench" / "core" / "belief.py"}


def _our_modules() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def restated_kpi_lists(source: str) -> list[int]:
    """Lines of tuple, list, set or dict literals that write out three or more of the KPI names."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Tuple | ast.List | ast.Set):
            items = node.elts
        elif isinstance(node, ast.Dict):
            items = [k for k in node.keys if k is not None]
        else:
            continue
        named = {e.value for e in items if isinstance(e, ast.Constant) and e.value in KPI_NAMES}
        if len(named) >= 3:
            lines.append(node.lineno)
    return lines


def reward_formulas(source: str) -> list[int]:
    """Lines that read a utility column of the metrics (by index constant or by name) to compute with it."""
    utility_constants = {"K_UWC", "K_UPUR", "K_UAFD"}
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Name) and node.id.lstrip("_") in utility_constants:
            lines.append(node.lineno)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "index":
            if any(isinstance(a, ast.Constant) and a.value in UTILITIES for a in node.args):
                lines.append(node.lineno)
    return lines


def test_kpis__the_detectors_find_a_planted_copy():
    planted = 'COLS = ("nsw", "workforce_cost", "utilization", "downtime")\nLABELS = {"nsw": 1, "downtime": 2, ' \
              '"utilization": 3}\nok = ("nsw", "seed")\n'
    assert sorted(restated_kpi_lists(planted)) == [1, 2]
    planted = "r = np.sqrt(last[:, K_UPUR] * last[:, _K_UAFD])\nk = METRICS.index('u_downtime')\nn = last[:, K_NSW]\n"
    assert sorted(reward_formulas(planted)) == [1, 1, 2]


@pytest.mark.slow
def test_kpis__no_module_writes_the_kpi_list_again():
    found = []
    for path in _our_modules():
        # an Alembic revision writes out the schema of its day: it must not follow the table when a KPI changes
        if path == TABLE or REVISIONS in path.parents:
            continue
        found += [f"{path.relative_to(ROOT)}:{line}" for line in restated_kpi_lists(path.read_text())]
    assert not found, ("these lines write out the KPI names again; import KPI_NAMES (or KPI_LABELS, KPIS) from "
                       f"wfbench.core.kpis instead: {found}")


@pytest.mark.slow
def test_kpis__no_module_computes_a_reward_from_the_utilities_again():
    found = []
    for path in _our_modules():
        if path in REWARD_HOMES or path in STATE_REBUILDERS or path == TABLE:
            continue
        found += [f"{path.relative_to(ROOT)}:{line}" for line in reward_formulas(path.read_text())]
    assert not found, ("these lines compute with the utility columns outside wfbench/core/reward.py; call "
                       f"wfbench.core.reward.step_reward instead: {found}")


def test_kpis__the_table_orders_every_report():
    assert KPI_NAMES == ("workforce_cost", "utilization", "downtime", "nsw")
    assert KPI_NAMES[-1] == SCORE and MEASURED == KPI_NAMES[:-1]
    assert METRICS[: len(KPI_NAMES)] == KPI_NAMES and METRICS[len(KPI_NAMES):len(KPI_NAMES) + 3] == UTILITIES
    assert [k.utility for k in KPIS] == [*UTILITIES, None]
    assert {BY_NAME[k].better for k in KPI_NAMES} == {"lower", "band", "higher"}


def test_kpis__scores_point_the_better_way():
    assert kpi_score("nsw", 0.7) > kpi_score("nsw", 0.6)
    assert kpi_score("downtime", 0.1) > kpi_score("downtime", 0.2)
    assert kpi_score("workforce_cost", 30.0) > kpi_score("workforce_cost", 40.0)
    assert kpi_score("utilization", 0.74) > kpi_score("utilization", 0.9) == kpi_score("utilization", 0.6)
    with pytest.raises(ValueError, match="unknown KPI 'speed'; allowed: workforce_cost, utilization"):
        kpi_score("speed", 1.0)


def test_kpis__every_frame_and_store_reads_the_table():
    from wfbench.leaderboard.store import KPI_COLUMNS

    import wfbench

    df = wfbench.evaluate("heuristic", wfbench.ScenarioConfig.preset("small").replace(horizon=20), [0, 1])
    assert set(KPI_NAMES) | set(UTILITIES) <= set(df.columns)
    assert KPI_COLUMNS == KPI_NAMES


def test_reward__no_cost_is_the_geometric_mean_of_the_other_two_utilities():
    from wfbench import Simulator

    sim = Simulator(resolve_scenario("small"), [3, 4])
    sim.reset()
    none = {"dispatch": np.full((2, sim.M), sim.N), "workforce": np.zeros(2, dtype=int),
            "positioning": np.zeros((2, 2, sim.M))}
    for _ in range(5):
        nsw = sim.step(none)
    last = sim.state.last
    u = {name: last[:, METRICS.index(name)] for name in UTILITIES}
    assert step_reward("nsw", nsw, last) is nsw
    np.testing.assert_allclose(np.cbrt(u["u_cost"] * u["u_utilization"] * u["u_downtime"]), nsw, rtol=1e-12)
    np.testing.assert_array_equal(step_reward("nsw-no-cost", nsw, last),
                                  np.sqrt(u["u_utilization"] * u["u_downtime"]))
    with pytest.raises(ValueError, match="reward 'nsw2' is not allowed; allowed: nsw, nsw-no-cost"):
        step_reward("nsw2", nsw, last)
    assert set(REWARDS) == {"nsw", "nsw-no-cost"}



def test_kpis__the_welfare_is_the_cube_root_of_the_product_bit_for_bit():
    """Why the KPI table has no weight per utility: the welfare, read as weights, would round differently."""
    from wfbench import Simulator

    sim = Simulator(resolve_scenario("small"), list(range(8)))
    sim.reset()
    rng = np.random.default_rng(0)
    rows = []
    for _ in range(150):
        sim.step({"dispatch": rng.integers(0, sim.N + 1, (8, sim.M)), "workforce": rng.integers(0, 7, 8),
                  "positioning": rng.random((8, 2, sim.M))})
        rows += sim.state.last.tolist()
    rows = [r for r in rows if all(0.0 < r[METRICS.index(u)] < 1.0 for u in UTILITIES)]
    assert len(rows) > 500
    exact = weighted = 0
    for r in rows:
        u = [r[METRICS.index(name)] for name in UTILITIES]
        exact += r[METRICS.index(SCORE)] == (u[0] * u[1] * u[2]) ** (1 / 3)
        weighted += r[METRICS.index(SCORE)] == u[0] ** (1 / 3) * u[1] ** (1 / 3) * u[2] ** (1 / 3)
    assert exact == len(rows), "the compiled welfare is (u_cost * u_utilization * u_downtime) ** (1/3), bit for bit"
    assert weighted < len(rows), "a weight per utility would move the welfare's last bits (kpis.py says so)"

def test_reward__single_and_vector_environments_give_the_same_bits():
    import gymnasium

    from wfbench.envs.vector import WorkforceVectorEnv

    env = gymnasium.make("wfbench/Dispatch-v0", scenario="small", reward="nsw-no-cost").unwrapped
    venv = WorkforceVectorEnv("small", num_envs=1, kind="dispatch", reward="nsw-no-cost")
    env.reset(seed=11)
    venv.reset(seed=11)
    noop = np.full((1, env.M), env.N)
    for _ in range(40):
        _, r, *_ = env.step(noop[0])
        _, rv, *_ = venv.step(noop)
        assert r == rv[0]
