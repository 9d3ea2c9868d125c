"""The rolling-horizon staffing MILP (wfbench.solvers.staffing_mpc) on tiny instances solved by hand."""

import numpy as np
import pytest
from wfbench.solvers import SolverInputError
from wfbench.solvers.staffing_mpc import StaffingInstance, plan_staffing

SALARY = np.array([1.0, 1.5, 2.0])


def novices(n, H):
    return np.array([[n], [0], [0]], dtype=float) * np.ones((3, H))


def test_hires_come_hire_delay_early_and_as_late_as_that_allows():
    # one novice; demand 1 then 3 from step 4; a hire works 2 steps after it; one action per step
    inst = StaffingInstance(demand=[1, 1, 1, 1, 3, 3, 3, 3], capacity=[1, 1, 1], salary=SALARY, ready=novices(1, 8),
                            paid=novices(1, 8), hire_delay=2, notice_delay=1, max_headcount=5)
    res = plan_staffing(inst)
    # by hand: two novices (the cheapest capacity), hired at steps 1 and 2 (one per step, working from 3 and 4)
    assert res.status == "optimal" and res.solution.tolist() == [0, 1, 1, 0, 0, 0, 0, 0]
    assert res.detail["productive"][0].tolist() == [1, 1, 1, 2, 3, 3, 3, 3]
    assert res.detail["payroll"][0].tolist() == [1, 2, 3, 3, 3, 3, 3, 3]  # paid from the hire on
    assert (res.detail["coverage"] >= np.array([1, 1, 1, 1, 3, 3, 3, 3])).all() and res.detail["shortfall"].sum() == 0
    assert res.objective == pytest.approx(8 + 7 + 6 + 2e-3)  # payroll steps, and the two actions' small cost


def test_let_goes_stop_work_next_step_and_are_paid_through_the_notice():
    inst = StaffingInstance(demand=[3, 3, 1, 1, 1, 1, 1, 1], capacity=[1, 1, 1], salary=SALARY, ready=novices(3, 8),
                            paid=novices(3, 8), hire_delay=2, notice_delay=2, max_headcount=5, min_headcount=1)
    res = plan_staffing(inst)
    # by hand: demand 3 at step 1, so the first let-go is at step 1 (stops work at 2), the second at step 2
    assert res.solution.tolist() == [0, 4, 4, 0, 0, 0, 0, 0]
    assert res.detail["productive"][0].tolist() == [3, 3, 2, 1, 1, 1, 1, 1]
    assert res.detail["payroll"][0].tolist() == [3, 3, 3, 2, 1, 1, 1, 1]
    assert res.detail["shortfall"].sum() == 0


def test_a_jump_faster_than_the_lags_is_shortfall_not_an_impossible_plan():
    inst = StaffingInstance(demand=[0, 0, 3, 3], capacity=[1, 1, 1], salary=SALARY, ready=novices(0, 4),
                            paid=novices(0, 4), hire_delay=1, notice_delay=1, max_headcount=5, shortfall_cost=100.0)
    res = plan_staffing(inst)
    assert res.solution.tolist() == [1, 1, 1, 0]  # one a step: 1, 2 then 3 at work
    assert res.detail["productive"][0].tolist() == [0, 1, 2, 3]
    assert res.detail["shortfall"].tolist() == pytest.approx([0, 0, 1, 0])


def test_blocks_take_the_lags_at_their_latest_and_bad_input_is_refused():
    inst = StaffingInstance(demand=[1, 1, 1, 1, 3, 3, 3, 3], capacity=[1, 1, 1], salary=SALARY, ready=novices(1, 8),
                            paid=novices(1, 8), hire_delay=2, notice_delay=1, max_headcount=5)
    res = plan_staffing(inst, block=2)
    assert res.solution.tolist() == [1, 1, 0, 0, 0, 0, 0, 0]  # block 0's hires work from its last step + 2 = 3
    assert (res.detail["coverage"] >= inst.demand).all()
    with pytest.raises(SolverInputError, match="block = 0 is not allowed"):
        plan_staffing(inst, block=0)
    with pytest.raises(SolverInputError, match="ready must have shape"):
        plan_staffing(StaffingInstance(**{**inst.__dict__, "ready": np.ones((3, 2))}))


def test_a_node_limit_keeps_the_optimum_here_and_bad_limits_are_refused():
    inst = StaffingInstance(demand=[1, 1, 1, 1, 3, 3, 3, 3], capacity=[1, 1, 1], salary=SALARY, ready=novices(1, 8),
                            paid=novices(1, 8), hire_delay=2, notice_delay=1, max_headcount=5)
    res = plan_staffing(inst, node_limit=1000)
    assert res.status == "optimal" and res.solution.tolist() == plan_staffing(inst).solution.tolist()
    for bad in (0, -3, 2.5, True, "many"):
        with pytest.raises(SolverInputError, match=f"node_limit = {bad!r} is not allowed; allowed: an integer >= 1"):
            plan_staffing(inst, node_limit=bad)


def test_the_plan_solves_inside_the_highs_stdout_filter(monkeypatch):
    """HiGHS's stray printf (ERGO-Code/HiGHS#2783) is filtered around the MPC's solve, the same plan either way."""
    import contextlib

    from wfbench.solvers import staffing_mpc

    inst = StaffingInstance(demand=[1, 1, 1, 1, 3, 3, 3, 3], capacity=[1, 1, 1], salary=SALARY, ready=novices(1, 8),
                            paid=novices(1, 8), hire_delay=2, notice_delay=1, max_headcount=5)
    filtered = plan_staffing(inst)
    entered = []

    @contextlib.contextmanager
    def spy():
        entered.append(1)
        yield

    monkeypatch.setattr(staffing_mpc, "without_highs_stray", spy)
    plain = plan_staffing(inst)
    assert entered == [1]
    assert plain.solution.tolist() == filtered.solution.tolist() and plain.objective == filtered.objective


def _queue(max_headcount, **kw):
    # one novice serving 0.5 a step, 1 request arriving a step, 2 waiting now; a hire works 2 steps after it
    args = dict(demand=[1] * 10, capacity=[0.5, 0.5, 0.5], salary=SALARY, ready=novices(1, 10), paid=novices(1, 10),
                hire_delay=2, notice_delay=1, max_headcount=max_headcount, backlog0=2.0, backlog_cost=10.0)
    return StaffingInstance(**{**args, **kw})


def test_the_queue_carries_what_capacity_does_not_serve_and_hiring_drains_it():
    alone = plan_staffing(_queue(max_headcount=1))  # no slot: nobody can be hired
    # by hand: 0.5 served a step, so the backlog grows by 0.5 a step from the 2 waiting
    assert alone.status == "optimal" and alone.solution.tolist() == [0] * 10
    assert alone.detail["served"].tolist() == pytest.approx([0.5] * 10)
    assert alone.detail["backlog"].tolist() == pytest.approx([2 + 0.5 * (h + 1) for h in range(10)])
    res = plan_staffing(_queue(max_headcount=5))
    q = res.detail["backlog"]
    hires = [a for a in res.solution.tolist() if a == 1]
    assert len(hires) >= 2 and res.solution[0] == 1, "hires at once: the backlog is paid every step it waits"
    assert q.max() < alone.detail["backlog"].max() and q[-1] == pytest.approx(0.0), "drained by the horizon's end"
    assert np.all(res.detail["served"] <= res.detail["coverage"] + 1e-9), "served at most the people's capacity"
    # arrivals - served is the backlog's change, step by step, from the 2 waiting
    assert np.diff(np.concatenate([[2.0], q])) == pytest.approx(1.0 - res.detail["served"])
    assert res.detail["productive"][0, -1] == 2, "once drained, the 2 novices that 1 request a step needs"


def test_a_backlog_waiting_now_is_staffed_for_where_coverage_alone_is_not():
    # capacity covers the arrivals exactly: without a queue nothing to do; with 3 waiting, a hire to drain them
    inst = StaffingInstance(demand=[1] * 12, capacity=[1, 1, 1], salary=SALARY, ready=novices(1, 12),
                            paid=novices(1, 12), hire_delay=1, notice_delay=1, max_headcount=3)
    assert plan_staffing(inst).solution.tolist() == [0] * 12
    res = plan_staffing(StaffingInstance(**{**inst.__dict__, "backlog0": 3.0, "backlog_cost": 10.0}))
    assert res.solution[0] == 1 and res.detail["backlog"][-1] == pytest.approx(0.0)
    none = plan_staffing(StaffingInstance(**{**inst.__dict__, "backlog0": 0.0, "backlog_cost": 10.0}))
    assert none.solution.tolist() == [0] * 12 and none.detail["backlog"].sum() == pytest.approx(0.0)
    # served at a full rate twice the capacity coverage asks for (a target utilization of 0.5): the novice drains
    # the 3 waiting alone, one a step beside the arrivals; a hire would save 1 request-step for 2 steps' pay
    fast = plan_staffing(StaffingInstance(**{**inst.__dict__, "backlog0": 3.0, "backlog_cost": 1.0,
                                             "service": [2.0, 2.0, 2.0]}))
    assert fast.solution.tolist() == [0] * 12 and fast.detail["backlog"][:4].tolist() == pytest.approx([2, 1, 0, 0])


@pytest.mark.parametrize("field, bad, says", [
    ("backlog0", -1.0, "backlog0 must be finite numbers >= 0"),
    ("backlog0", "many", "backlog0 must be numbers"),
    ("backlog_cost", -2.0, "backlog_cost = -2.0 is not allowed; allowed: a finite number >= 0"),
    ("backlog_cost", "high", "backlog_cost = 'high' is not allowed; allowed: a finite number >= 0"),
])
def test_a_bad_queue_is_refused_in_one_line(field, bad, says):
    with pytest.raises(SolverInputError, match=says) as err:
        plan_staffing(_queue(max_headcount=5, **{field: bad}))
    assert "\n" not in str(err.value)


def test_a_limit_before_an_incumbent_gives_no_actions_and_the_queue_they_leave(monkeypatch):
    """HiGHS stopped with no plan: the no-action plan, its backlog played out as the queue's rows say."""
    import scipy.optimize

    class Stopped:
        x, status, message = None, 1, "node limit reached"

    monkeypatch.setattr(scipy.optimize, "milp", lambda *a, **k: Stopped())
    res = plan_staffing(_queue(max_headcount=5), node_limit=1)
    assert res.status == "time_limit" and res.solution.tolist() == [0] * 10
    assert res.detail["served"].tolist() == pytest.approx([0.5] * 10)
    assert res.detail["backlog"].tolist() == pytest.approx([2 + 0.5 * (h + 1) for h in range(10)])
    assert res.detail["shortfall"].tolist() == pytest.approx([0.5] * 10), "coverage's shortfall beside the queue"
