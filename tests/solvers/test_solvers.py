"""solvers/: agreement of the methods, known OR-Library optima, staffing by hand, bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from wfbench.solvers import SolverInputError, assignment, facility_location, orlib, staffing

# the small OR-Library instances travel with the tests (tests/data/orlib/README.md)
ORLIB = Path(__file__).resolve().parents[1] / "data" / "orlib"

UFL_OPTIMA = {
    "cap71": 932615.750, "cap72": 977799.400, "cap73": 1010641.450, "cap74": 1034976.975,
    "cap101": 796648.437, "cap102": 854704.200, "cap103": 893782.112, "cap104": 928941.750,
    "cap131": 793439.562, "cap132": 851495.325, "cap133": 893076.712, "cap134": 928941.750,
}
PMED_OPTIMA = {"pmed1": 5819, "pmed2": 4093, "pmed3": 4250, "pmed4": 3034, "pmed5": 1355}

LP_VARIANTS = [("lp", "HIGHS"), ("lp", "OSQP")]


def _all_methods(C, mask=None, u=None):
    out = {m: assignment.solve(C, mask=mask, unassigned_cost=u, method=m) for m in ("exact", "milp")}
    for m, s in LP_VARIANTS:
        out[f"{m}-{s}"] = assignment.solve(C, mask=mask, unassigned_cost=u, method=m, lp_solver=s)
    return out


def _check_solution(C, mask, u, res):
    """The returned assignment is feasible and its objective is what it claims."""
    n, m = C.shape
    sol = res.solution
    assert sol.shape == (n,)
    used = sol[sol >= 0]
    assert len(set(used.tolist())) == used.size, "a column used twice"
    assert ((sol >= -1) & (sol < m)).all()
    if mask is not None:
        assert all(mask[i, sol[i]] for i in range(n) if sol[i] >= 0)
    if u is None:
        assert used.size == min(n, m)
    total = sum(C[i, sol[i]] for i in range(n) if sol[i] >= 0)
    if u is not None:
        total += sum(np.broadcast_to(u, (n,))[i] for i in range(n) if sol[i] < 0)
    assert res.objective == pytest.approx(total, abs=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_assignment_methods_agree_on_random_instances(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 9, size=2)
    C = rng.integers(0, 6, size=(n, m)).astype(float)  # small integers: many ties
    mask = rng.random((n, m)) < 0.8 if seed % 3 else None
    u = rng.uniform(1, 6, size=n) if seed % 2 else None
    results = _all_methods(C, mask, u)
    exact = results["exact"]
    if exact.status == "infeasible":
        assert all(r.status == "infeasible" for r in results.values()), results
        return
    assert exact.status == "optimal"
    for name, r in results.items():
        _check_solution(C, mask, u, r)
        assert r.objective == pytest.approx(exact.objective, abs=1e-6), name
        if r.bound is not None:
            assert r.bound <= exact.objective + 1e-6, name


def test_assignment_degenerate_cases():
    # all ties: any perfect assignment is optimal
    for r in _all_methods(np.ones((4, 6))).values():
        assert r.objective == pytest.approx(4.0)
    # all pairs forbidden: infeasible without the unassigned option, all unassigned with it
    C = np.arange(6.0).reshape(2, 3)
    none = np.zeros((2, 3), dtype=bool)
    for r in _all_methods(C, mask=none).values():
        assert r.status == "infeasible" and (r.solution == -1).all() and math.isnan(r.objective)
    for r in _all_methods(C, mask=none, u=[2.0, 5.0]).values():
        assert r.objective == pytest.approx(7.0) and (r.solution == -1).all()
    # 0 x n and n x 0
    for shape in ((0, 3), (0, 0)):
        r = assignment.solve(np.zeros(shape))
        assert r.status == "empty" and r.solution.shape == (0,) and r.objective == 0.0
    r = assignment.solve(np.zeros((2, 0)), unassigned_cost=1.5, method="lp")
    assert r.objective == pytest.approx(3.0) and (r.solution == -1).all()
    # a pair is used only when cheaper than leaving the row
    r = assignment.solve([[5.0, 1.0]], unassigned_cost=2.0)
    assert r.solution.tolist() == [1] and r.objective == 1.0
    r = assignment.solve([[5.0, 3.0]], unassigned_cost=2.0, method="milp")
    assert r.solution.tolist() == [-1] and r.objective == 2.0
    # more rows than columns: every column is used
    r = assignment.solve([[1.0], [0.5], [3.0]])
    assert r.solution.tolist() == [-1, 0, -1]


def test_forbidden_pairs_may_hold_nan():
    C = np.array([[np.nan, 1.0], [2.0, np.inf]])
    mask = np.array([[False, True], [True, False]])
    for r in _all_methods(C, mask=mask).values():
        assert r.solution.tolist() == [1, 0] and r.objective == 3.0


def test_lp_resolve_reuses_the_compiled_problem():
    rng = np.random.default_rng(5)
    first = assignment.solve(rng.random((7, 9)), method="lp")  # may be compiled by an earlier test
    again = [assignment.solve(rng.random((7, 9)), method="lp") for _ in range(3)]
    assert all(not r.detail["rebuilt"] for r in again)
    assert first.status == "optimal"
    exact = assignment.solve(rng.random((7, 9)))
    assert exact.solve_time_s >= 0


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_assignment_rejects_non_finite_costs(bad):
    C = np.ones((3, 3))
    C[1, 2] = bad
    with pytest.raises(SolverInputError, match=r"cost\[1, 2\].*finite"):
        assignment.solve(C)


def test_assignment_rejects_bad_arguments():
    with pytest.raises(SolverInputError, match="method='hungarian' is not allowed; allowed: exact, milp, lp"):
        assignment.solve(np.ones((2, 2)), method="hungarian")
    with pytest.raises(SolverInputError, match="lp_solver"):
        assignment.solve(np.ones((2, 2)), method="lp", lp_solver="GUROBI")
    with pytest.raises(SolverInputError, match="mask must have the shape"):
        assignment.solve(np.ones((2, 2)), mask=np.ones((3, 2), dtype=bool))
    with pytest.raises(SolverInputError, match="must be 2-D"):
        assignment.solve(np.ones(3))
    with pytest.raises(SolverInputError, match=r"unassigned_cost must be a scalar or have shape \(2,\)"):
        assignment.solve(np.ones((2, 2)), unassigned_cost=[1, 2, 3])
    with pytest.raises(SolverInputError, match="time_limit"):
        assignment.solve(np.ones((2, 2)), method="milp", time_limit=-1)


# -- OR-Library ---------------------------------------------------------------------------------
@pytest.mark.slow
def test_assign100_optimum():
    C = orlib.read_assignment(ORLIB / "assign" / "assign100.txt")
    assert C.shape == (100, 100)
    for method in ("exact", "milp", "lp"):
        assert assignment.solve(C, method=method).objective == 305


@pytest.mark.parametrize("name", sorted(UFL_OPTIMA))
def test_ufl_reaches_known_optimum(name):
    inst = orlib.read_uflp(ORLIB / "uflp" / f"{name}.txt")
    opt = UFL_OPTIMA[name]
    exact = facility_location.solve_ufl(inst.fixed_cost, inst.cost, method="milp")
    assert exact.status == "optimal"
    assert exact.objective == pytest.approx(opt, abs=1e-2)
    lp = facility_location.solve_ufl(inst.fixed_cost, inst.cost, method="lp")
    assert lp.bound <= opt + 1e-2 and lp.objective >= opt - 1e-2
    ls = facility_location.solve_ufl(inst.fixed_cost, inst.cost, method="local-search")
    assert ls.objective >= opt - 1e-2
    assert ls.objective <= 1.01 * opt  # greedy + swaps stays within 1% on these instances
    # each client is served by its cheapest open facility
    a = exact.detail["assignment"]
    assert set(a.tolist()) <= set(exact.solution.tolist())


@pytest.mark.parametrize("name", sorted(PMED_OPTIMA))
def test_p_median_reaches_known_optimum(name):
    inst = orlib.read_p_median(ORLIB / "pmed" / f"{name}.txt")
    opt = PMED_OPTIMA[name]
    exact = facility_location.solve_p_median(inst.dist, inst.p, method="milp")
    assert exact.status == "optimal" and exact.objective == opt
    assert exact.solution.size == inst.p
    lp = facility_location.solve_p_median(inst.dist, inst.p, method="lp")
    assert lp.bound <= opt + 1e-6 and lp.objective >= opt and lp.solution.size == inst.p
    ls = facility_location.solve_p_median(inst.dist, inst.p, method="local-search")
    assert opt <= ls.objective <= 1.05 * opt and ls.solution.size == inst.p


def test_pmed1_repeated_edges_keep_the_last_cost():
    # keeping the cheapest of the repeated edges gives 5718 instead of the published 5819
    inst = orlib.read_p_median(ORLIB / "pmed" / "pmed1.txt")
    assert facility_location.solve_p_median(inst.dist, inst.p, method="local-search").objective == 5819


def test_p_median_small_by_hand(tmp_path):
    # path 1 - 2 - 3 - 4 with costs 1, 5, 1: p = 2 opens one of {1,2} and one of {3,4}, cost 2
    f = tmp_path / "line.txt"
    f.write_text("4 4 2\n1 2 1\n2 3 9\n3 4 1\n2 3 5\n")  # 2-3 listed twice: the last (5) counts
    inst = orlib.read_p_median(f)
    assert inst.dist[0, 3] == 7 and inst.p == 2
    for method in facility_location.METHODS:
        r = facility_location.solve_p_median(inst.dist, 2, method=method)
        assert r.objective == 2.0
        assert len(set(r.solution.tolist()) & {0, 1}) == 1
    w = facility_location.solve_p_median(inst.dist, 1, weights=[0, 0, 0, 1])
    assert w.solution.tolist() == [3] and w.objective == 0.0


def test_ufl_small_by_hand():
    # opening both facilities (3 + 3) beats one (3 + 10): clients pay 1 each
    f = [3.0, 3.0]
    C = [[1.0, 1.0, 11.0, 11.0], [11.0, 11.0, 1.0, 1.0]]
    for method in facility_location.METHODS:
        r = facility_location.solve_ufl(f, C, method=method)
        assert r.solution.tolist() == [0, 1] and r.objective == 10.0
        assert r.detail["assignment"].tolist() == [0, 0, 1, 1]
    r = facility_location.solve_ufl([30.0, 30.0], C, method="local-search")
    assert r.solution.size == 1 and r.objective == 30.0 + 24.0


def test_milp_time_limit_returns_best_solution_with_gap():
    rng = np.random.default_rng(0)
    pts = rng.random((150, 2))
    D = np.abs(pts[:, None, :] - pts[None, :, :]).sum(-1)
    r = facility_location.solve_p_median(D, 15, method="milp", time_limit=0.01)
    assert r.status == "time_limit"
    assert r.solution.size == 15 and math.isfinite(r.objective)
    assert "time limit" in r.message.lower()
    full = facility_location.solve_p_median(D, 15, method="local-search")
    assert r.objective >= full.objective * 0.5  # a real solution, not a placeholder


@pytest.mark.parametrize("p", [0, 5, -1, 2.5, True])
def test_p_median_rejects_infeasible_p(p):
    with pytest.raises(SolverInputError, match=r"p = .* is not allowed; allowed: an integer with 1 <= p <= 4"):
        facility_location.solve_p_median(np.ones((4, 4)), p)


def test_facility_location_rejects_bad_costs():
    with pytest.raises(SolverInputError, match=r"cost\[0, 1\] = nan"):
        facility_location.solve_ufl([1.0, 1.0], [[1.0, np.nan], [1.0, 1.0]])
    with pytest.raises(SolverInputError, match=r"fixed_cost must be a scalar or have shape \(2,\)"):
        facility_location.solve_ufl([1.0], [[1.0], [1.0]])
    with pytest.raises(SolverInputError, match="weights"):
        facility_location.solve_p_median(np.ones((3, 3)), 1, weights=[1, -1, 1])
    with pytest.raises(SolverInputError, match="method"):
        facility_location.solve_ufl([1.0], [[1.0]], method="exact")


@pytest.mark.parametrize(
    ("reader", "text", "message"),
    [
        (orlib.read_uflp, "2 1\n10 5\n10\n", "file ends"),
        (orlib.read_uflp, "2 1\n10 5\n10 6\n7\n1 x\n", "expected 2 numbers"),
        (orlib.read_uflp, "2 1\n10 5\n10 6\n7\n1 2 3\n", "unexpected token"),
        (orlib.read_uflp, "0 3\n", "must be >= 1"),
        (orlib.read_p_median, "3 1 1\n1 2 4\n", "not connected"),
        (orlib.read_p_median, "3 2 4\n1 2 4\n2 3 1\n", "p = 4 exceeds"),
        (orlib.read_p_median, "3 2 1\n1 2 4\n2 7 1\n", "not a vertex number"),
        (orlib.read_p_median, "3 2 1\n1 2 4\n", "file ends"),
        (orlib.read_assignment, "2\n1 2 3\n", "file ends after 3 of 4"),
        (orlib.read_assignment, "two\n", "expected an integer|expected n"),
        (orlib.read_assignment, "", "file ends"),
    ],
)
def test_malformed_orlib_files(tmp_path, reader, text, message):
    f = tmp_path / "bad.txt"
    f.write_text(text)
    with pytest.raises(orlib.OrlibFormatError, match=message) as info:
        reader(f)
    assert str(f) in str(info.value)


def test_orlib_missing_file(tmp_path):
    with pytest.raises(orlib.OrlibFormatError, match="cannot read"):
        orlib.read_assignment(tmp_path / "nope.txt")


# -- staffing -----------------------------------------------------------------------------------
def test_erlang_by_hand():
    # M/M/2 with offered load 1: B = (1/2) / (1 + 1 + 1/2) = 0.2, C = 2 * 0.2 / (2 - 0.8) = 1/3
    assert staffing.erlang_b(2, 1.0) == pytest.approx(0.2)
    assert staffing.erlang_c(2, 1.0) == pytest.approx(1 / 3)
    # M/M/1: the waiting probability is the utilization
    assert staffing.erlang_c(1, 0.6) == pytest.approx(0.6)
    # M/M/3 with a = 2: B = (8/6) / (1 + 2 + 2 + 8/6) = 4/19, C = 3 B / (3 - 2 (1 - B)) = 4/9
    assert staffing.erlang_c(3, 2.0) == pytest.approx(4 / 9)
    assert staffing.mean_wait(3, 2.0, mean_duration=1.0) == pytest.approx((4 / 9) / 1.0)
    assert staffing.erlang_c(3, 3.0) == 1.0 and staffing.erlang_c(4, 0.0) == 0.0
    # large c stays finite and in [0, 1] (the recursion never forms a factorial)
    assert 0.0 < staffing.erlang_c(2000, 1950.0) < 1.0


def test_square_root_staffing_by_hand():
    # R = 0.5 * 20 = 10; beta 1: 10 + sqrt(10) = 13.16 -> 14
    plan = staffing.square_root_staffing(0.5, 20.0, beta=1.0)
    assert plan.servers == 14 and plan.offered_load == 10.0 and plan.utilization == pytest.approx(10 / 14)
    # utilization target 0.8: 10 / 0.8 = 12.5 -> 13
    assert staffing.square_root_staffing(0.5, 20.0, target_utilization=0.8).servers == 13
    # Halfin-Whitt at beta = 0.5: alpha = 1 / (1 + 0.5 Phi(0.5) / phi(0.5)) = 1 / (1 + 0.5 * 0.69146 / 0.35207)
    alpha = 1.0 / (1.0 + 0.5 * 0.691462461 / 0.352065327)
    assert staffing.halfin_whitt_beta(alpha) == pytest.approx(0.5, abs=1e-6)
    plan = staffing.square_root_staffing(0.5, 20.0, target_wait_prob=0.2)
    assert plan.erlang_servers == 14  # C(13, 10) = 0.29 > 0.2 >= C(14, 10) = 0.17
    assert staffing.erlang_c(13, 10.0) > 0.2 >= staffing.erlang_c(14, 10.0)
    assert abs(plan.servers - plan.erlang_servers) <= 1
    # no load, no staff beyond the minimum
    assert staffing.square_root_staffing(0.0, 5.0, beta=1.0, min_servers=2).servers == 2


def test_job_duration_by_hand():
    # travel 10 each way + service 3 = 23 per visit; mean fix prob .25*.49 + .5*.7 + .25*.84 = 0.6825
    d = staffing.job_duration(10, 3, [0.49, 0.70, 0.84], level_mix=[0.25, 0.5, 0.25])
    assert d == pytest.approx(23 / 0.6825)
    assert staffing.job_duration(4, 2, 1.0, return_trip=False) == 6.0


def test_staffing_rejects_bad_input():
    with pytest.raises(SolverInputError, match="exactly one"):
        staffing.square_root_staffing(1.0, 2.0)
    with pytest.raises(SolverInputError, match="exactly one"):
        staffing.square_root_staffing(1.0, 2.0, beta=1.0, target_utilization=0.5)
    with pytest.raises(SolverInputError, match="arrival_rate = nan"):
        staffing.square_root_staffing(float("nan"), 2.0, beta=1.0)
    with pytest.raises(SolverInputError, match="target_utilization"):
        staffing.square_root_staffing(1.0, 2.0, target_utilization=1.5)
    with pytest.raises(SolverInputError, match="servers"):
        staffing.erlang_c(-1, 1.0)
    with pytest.raises(SolverInputError, match="fix_prob"):
        staffing.job_duration(1, 1, 0.0)


# -- sparse candidate graphs (lap.lap_sparse, facility_location.p_median_sparse; docs/solvers.md) ---------------
def test_knn_manhattan_is_the_brute_force_order():
    from wfbench.solvers.lap import knn_manhattan

    rng = np.random.default_rng(0)
    for _ in range(200):
        n, nq, k = int(rng.integers(1, 60)), int(rng.integers(1, 30)), int(rng.integers(1, 10))
        px, py = (rng.integers(0, 12, n).astype(float) for _ in range(2))  # many ties
        qx, qy = (rng.integers(-3, 15, nq).astype(float) for _ in range(2))  # queries outside the points' box too
        idx, dist = np.empty((nq, k), dtype=np.int64), np.empty((nq, k))
        count = knn_manhattan(qx, qy, px, py, k, idx, dist)
        for q in range(nq):
            d = np.abs(qx[q] - px) + np.abs(qy[q] - py)
            assert count[q] == min(k, n)
            np.testing.assert_array_equal(idx[q, :count[q]], np.lexsort((np.arange(n), d))[:k])
            np.testing.assert_array_equal(dist[q, :count[q]], d[idx[q, :count[q]]])


def _csr(mask, C):
    ii, jj = np.nonzero(mask)
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))]).astype(np.int64)
    return indptr, jj.astype(np.int64), C[ii, jj].astype(np.float64)


def test_lap_sparse_is_exact_on_its_graph():
    """The compiled sparse solver against scipy on the same graph, ties, forbidden pairs and "nobody" included."""
    from scipy.optimize import linear_sum_assignment
    from wfbench.solvers.lap import lap_sparse

    rng = np.random.default_rng(1)
    for _ in range(500):
        nr, nc = int(rng.integers(1, 9)), int(rng.integers(1, 12))
        C = rng.integers(0, 5, (nr, nc)).astype(float)
        mask = rng.random((nr, nc)) < 0.7
        nobody = np.where(rng.random(nr) < 0.5, rng.integers(0, 8, nr).astype(float), np.inf)
        col4row = np.empty(nr, dtype=np.int64)
        total = lap_sparse(nc, *_csr(mask, C), nobody, col4row)
        W = np.full((nr, nc + nr), np.inf)
        W[:, :nc] = np.where(mask, C, np.inf)
        W[np.arange(nr), nc + np.arange(nr)] = nobody
        try:
            r, c = linear_sum_assignment(W)
            ref = W[r, c].sum()
        except ValueError:
            ref = math.inf
        assert total == ref
        if math.isfinite(total):
            made = col4row[col4row >= 0]
            assert len(set(made.tolist())) == made.size
            assert all(mask[i, col4row[i]] for i in np.flatnonzero(col4row >= 0))
            assert sum(C[i, j] if j >= 0 else nobody[i] for i, j in enumerate(col4row)) == total
        if np.isinf(nobody).all() and math.isfinite(total):  # the plain reference agrees
            ref_sol = assignment.solve_sparse(C, mask)
            assert (ref_sol.solution >= 0).all() and ref_sol.objective == total


def test_sparse_assignment_equals_the_dense_one_where_the_dense_uses_candidate_edges():
    """k nearest of each row by distance: the optimum is the dense one whenever a dense optimum lies on the graph.

    On random dispatch-like instances (requests and people in a grid, cost = distance +
    a level penalty) the sparse optimum (``lap_sparse``, and the plain reference
    ``assignment.solve_sparse``) always equals the dense optimum when the dense solution's
    pairs are all candidate edges, and always when k >= the people. Where neither holds
    it may be worse, never better; the test counts how often and by how much.
    """
    from wfbench.solvers.lap import lap_sparse

    rng = np.random.default_rng(2)
    on_graph = off_graph = worse = 0
    for _ in range(400):
        nr, npl, k = int(rng.integers(1, 10)), int(rng.integers(1, 25)), int(rng.integers(1, 9))
        fr, pp = rng.integers(0, 30, (nr, 2)), rng.integers(0, 30, (npl, 2))
        D = np.abs(fr[:, None, :] - pp[None, :, :]).sum(axis=-1).astype(float)
        C = D + rng.choice([2.08, 0.857, 0.381], size=npl)[None, :]  # revisit penalties of the three levels
        dense = assignment.solve(C)
        served = min(nr, npl)
        mask = assignment.candidate_mask(D, k)
        col4row = np.empty(nr, dtype=np.int64)
        big = 1.0 + np.where(mask, C, 0.0).max(axis=1).sum()
        total = lap_sparse(npl, *_csr(mask, C), np.full(nr, big), col4row)
        made = int((col4row >= 0).sum())
        sparse_obj = total - (nr - made) * big
        ref = assignment.solve_sparse(C, mask)
        assert int((ref.solution >= 0).sum()) == made and ref.objective == pytest.approx(sparse_obj, abs=1e-9)
        rows = np.flatnonzero(dense.solution >= 0)
        if k >= npl or mask[rows, dense.solution[rows]].all():
            on_graph += 1
            assert made == served and sparse_obj == pytest.approx(dense.objective, abs=1e-9)
        else:
            off_graph += 1
            assert made < served or sparse_obj >= dense.objective - 1e-9
            worse += made < served or sparse_obj > dense.objective + 1e-9
    assert on_graph > 300 and worse <= off_graph  # 400 instances: most dense optima lie on the graph


def test_p_median_sparse_with_complete_lists_is_the_dense_heuristic():
    """k >= the sites: the same greedy picks and swaps as greedy_open + local_search (integer costs: exact sums)."""
    from wfbench.solvers.facility_location import p_median_sparse
    from wfbench.solvers.lap import knn_manhattan

    rng = np.random.default_rng(3)
    for _ in range(300):
        m = int(rng.integers(2, 25))
        p = int(rng.integers(1, m + 1))
        xy = rng.integers(0, 10, (m, 2)).astype(float)
        w = rng.integers(1, 4, m).astype(float)
        C = np.abs(xy[:, None] - xy[None]).sum(-1) * w[None, :]
        dense = facility_location.greedy_open(C, np.zeros(m), p)
        facility_location.local_search(C, np.zeros(m), dense, p, 1000, 1e-9)
        idx, d = np.empty((m, m), dtype=np.int64), np.empty((m, m))
        count = knn_manhattan(xy[:, 0], xy[:, 1], xy[:, 0], xy[:, 1], m, idx, d)
        sparse, _ = p_median_sparse(m, idx, d * w[:, None], count, np.full(m, np.inf), p, 1000, 1e-9)
        np.testing.assert_array_equal(sparse, dense)


def test_p_median_sparse_on_k_nearest_lists_against_the_dense_heuristic():
    """k = 8 nearest sites per client on uniform instances: the medians' dense cost against the dense heuristic's.

    The sparse objective is the dense one for every median set that gives each client one
    of its k nearest (checked); the search may then end elsewhere than the dense one.
    Measured here (fixed seeds): the mean excess is below 0.5% and none above 5%.
    """
    from wfbench.solvers.facility_location import p_median_sparse
    from wfbench.solvers.lap import knn_manhattan

    rng = np.random.default_rng(4)
    excess = []
    for _ in range(40):
        m = int(rng.integers(20, 120))
        p = int(rng.integers(m // 2, m + 1))  # the positioning rule's regime: p = headcount + 1, near the sites
        xy = rng.integers(0, 200, (m, 2)).astype(float)
        w = 0.1 + rng.random(m)
        C = np.abs(xy[:, None] - xy[None]).sum(-1) * w[None, :]
        dense = facility_location.greedy_open(C, np.zeros(m), p)
        facility_location.local_search(C, np.zeros(m), dense, p, 1000, 1e-9)
        k = 8
        idx, d = np.empty((m, k + 1), dtype=np.int64), np.empty((m, k + 1))
        knn_manhattan(xy[:, 0], xy[:, 1], xy[:, 0], xy[:, 1], k + 1, idx, d)
        sparse, _ = p_median_sparse(m, idx[:, :k].copy(), d[:, :k] * w[:, None], np.full(m, k), w * d[:, k], p, 1000,
                                    1e-9)
        assert sparse.sum() == p
        served = sparse[idx[:, :k]].any(axis=1)
        if served.all():  # each client has an open candidate: the sparse objective is the dense one
            sparse_obj = sum(min(d[j, t] * w[j] for t in range(k) if sparse[idx[j, t]]) for j in range(m))
            assert sparse_obj == pytest.approx(C[sparse].min(axis=0).sum())
        ref = C[dense].min(axis=0).sum()
        excess.append((C[sparse].min(axis=0).sum() - ref) / max(ref, 1e-12))
    assert np.mean(excess) < 0.005 and np.max(excess) < 0.05


def test_highs_stray_line_is_dropped_and_other_output_kept(capfd):
    """HiGHS's printf past output_flag does not reach stdout; anything else written meanwhile does, in order."""
    import os
    import threading

    from wfbench.solvers.result import HIGHS_STRAY, without_highs_stray

    print("before", flush=True)
    with without_highs_stray():
        os.write(1, HIGHS_STRAY + b"\n")
        os.write(1, b"from C: kept\n")
        other = threading.Thread(target=lambda: os.write(1, b"another thread: kept\n"))
        other.start()
        other.join()
        with without_highs_stray():  # a solve in flight in another thread shares the capture
            os.write(1, HIGHS_STRAY + b"\r\n")
        os.write(1, b"no newline at the end")
    print("\nafter", flush=True)
    out = capfd.readouterr().out
    assert "HighsMipSolverData" not in out
    assert out == "before\nfrom C: kept\nanother thread: kept\nno newline at the end\nafter\n"


def test_milp_solvers_run_under_the_stdout_filter(monkeypatch):
    """The assignment and p-median MILPs solve inside without_highs_stray (the MPC's: test_mpc_milp)."""
    import contextlib


    calls = []

    @contextlib.contextmanager
    def spy():
        calls.append(1)
        yield

    for mod in (assignment, facility_location):
        monkeypatch.setattr(mod, "without_highs_stray", spy)
    rng = np.random.default_rng(0)
    assignment.solve(rng.random((4, 5)), method="milp")
    assert len(calls) == 1
    facility_location.solve_p_median(rng.random((6, 4)), 2, method="milp")
    assert len(calls) == 2
