"""A built-in rule is one row of wfbench.policies.rules.RULES, and every other table is made from it."""

import numpy as np
import pytest
from wfbench.policies import kernels as K
from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.decisions import DECISIONS, LABELS, OTHERS
from wfbench.policies.rules import CODES, HP_BY_NAME, HYPERPARAMETERS, RULES, code

from wfbench.core.actions import AGENTS
from wfbench.scenarios.resolve import resolve_scenario


def test_rules__codes_count_from_each_decisions_no_op():
    from wfbench import Simulator

    sim = Simulator(resolve_scenario("small"), [5])
    sim.reset()
    obs = sim.observe()
    does_nothing = {"dispatch": sim.N, "workforce": 0, "positioning": 0.0}
    assert list(CODES) == list(AGENTS)
    for decision in AGENTS:
        rows = [r for r in RULES if r.decision == decision]
        assert [r.code for r in rows] == list(range(len(rows)))
        noop = BuiltinDecision(decision, 0, rows[0].name)  # code 0 is also what act passes the other decisions
        noop.reset([5])
        assert (noop.act(obs)[decision] == does_nothing[decision]).all()
    assert (K.D_NEAREST, K.W_THRESHOLD, K.P_FACILITY) == (code("dispatch", "nearest"), code("workforce", "threshold"),
                                                         code("positioning", "facility-location"))
    with pytest.raises(KeyError, match="no built-in workforce rule 'hire-all'; rules: fixed, threshold"):
        code("workforce", "hire-all")


def test_rules__every_table_of_the_built_in_decisions_is_made_from_the_rows():
    for r in RULES:
        made = DECISIONS[r.decision][r.name]()
        assert isinstance(made, BuiltinDecision) and (made.decision, made.code, made.name) == (r.decision, r.code,
                                                                                                r.name)
        assert LABELS[r.decision][r.name] == r.label
        assert made.tunable == r.params and list(made.tunable) == list(r.tunes)
    for o in OTHERS:
        assert DECISIONS[o.decision][o.name] is o.make and LABELS[o.decision][o.name] == o.label
    assert sum(map(len, DECISIONS.values())) == len(RULES) + len(OTHERS), "a name is in both tables"


def test_rules__the_hyper_parameter_vector_is_the_fields_table():
    assert K.HP_FIELDS == tuple(HP_BY_NAME) and len(set(K.HP_FIELDS)) == len(HYPERPARAMETERS)
    assert K.HP_DEFAULTS == {h.name: h.default for h in HYPERPARAMETERS}
    # the kernels read a level's fix probability at HP_FIX0 + level
    fix = ("fix_novice", "fix_mid", "fix_expert")
    assert [K.HP_FIX0 + level for level in range(3)] == [K.HP_FIELDS.index(f) for f in fix]
    for r in RULES:
        for f in r.tunes:
            param = HP_BY_NAME[f].range
            assert param is not None, f"{r.name} tunes {f}, which has no range"
            assert param.check(HP_BY_NAME[f].default, f) == HP_BY_NAME[f].default, f"{f}'s default is out of range"
    pol = DECISIONS["workforce"]["threshold"]()
    np.testing.assert_array_equal(pol.hp, [h.default for h in HYPERPARAMETERS])
    with pytest.raises(ValueError, match="threshold has no tunable parameter 'noise'; allowed: high, low, cooldown"):
        pol.with_params(noise=0.1)
