"""`wfbench policies` (wfbench/cli/policies.py): every registered policy, grouped by family, with its decisions and
budget class; --family filters, --format json prints the same for tools (issue #54)."""

from __future__ import annotations

import json

import pytest
from wfbench.policies import registry
from wfbench.policies.table import FAMILIES, TABLE

from wfbench.cli import main


def _text(capsys, *args: str) -> list[str]:
    assert main(["policies", *args]) == 0
    return capsys.readouterr().out.splitlines()


def _json(capsys, *args: str) -> list[dict]:
    assert main(["policies", "--format", "json", *args]) == 0
    return json.loads(capsys.readouterr().out)


def _policy_lines(lines: list[str]) -> dict[str, str]:
    """name -> its line: the lines of policies (not the family headers, seed members or decision lists)."""
    return {line.split()[0]: line for line in lines
            if line and not line.startswith("[") and "#seedK" not in line.split()[0] and " decisions (for " not in line}


def test_it_lists_every_name_get_accepts_and_nothing_else(capsys):
    listed = _policy_lines(_text(capsys))
    # both ways: every listed name is a registered one that get() builds by name, and every registered name is listed
    assert set(listed) == set(TABLE)
    for name in listed:
        assert registry.parse_spec(name).kind == TABLE[name].kind
    accepted = {*registry.names(), *registry.lookahead_names(), *registry.names_of("learned")}
    assert accepted == set(listed), "every name policies.get takes by name (listed or not, lookaheads included)"
    assert [row["name"] for row in _json(capsys)] == list(listed), "the JSON lists the same, in the same order"


def test_it_groups_by_family_in_order_with_decisions_and_budget_class(capsys):
    lines = _text(capsys)
    headers = [line for line in lines if line.startswith("[")]
    assert [h[1:h.index("]")] for h in headers] == list(FAMILIES)
    family = None
    for line in lines:
        if line.startswith("["):
            family = line[1:line.index("]")]
        elif line.split() and line.split()[0] in TABLE:
            assert TABLE[line.split()[0]].family == family, line
    listed = _policy_lines(lines)
    assert listed["heuristic"].endswith("; decisions: Heuristic | Heuristic | Heuristic; budget: <= 1 ms")
    assert listed["rollout-solver-tuned-1ms"].startswith("rollout-solver-tuned-1ms a lookahead on solver-tuned, "
                                                         "the 1ms preset, sparse on city-sized worlds: ")
    assert listed["rollout-solver-tuned-1ms"].endswith("; budget: <= 10 ms")
    assert listed["mpc-ma-backlog"].endswith("Staffing MILP on ma, backlog | Forecast demand (ma, backlog); "
                                             "budget: not measured")
    assert listed["search-scalefree-general"].endswith("; budget: <= 100 ms")
    assert "heuristic-tuned        policies/tuned/heuristic-paper-64.json: " in listed["heuristic-tuned"]
    assert lines[-3].startswith("dispatch decisions (for Composite, D+W+P and fixed agents): none, nearest")


@pytest.mark.parametrize("family", list(FAMILIES))
def test_family_lists_that_family_only(capsys, family):
    lines = _text(capsys, "--family", family)
    assert [line for line in lines if line.startswith("[")] == [f"[{family}] {FAMILIES[family]}"]
    expected = [e.name for e in registry.entries(family)]
    assert list(_policy_lines(lines)) == expected and expected
    assert [row["name"] for row in _json(capsys, "--family", family)] == expected
    assert any(" decisions (for " in line for line in lines) == (family == "composite")


def test_an_unknown_family_is_one_line_naming_the_allowed_ones(capsys):
    assert main(["policies", "--family", "mcp"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == ("wfbench: error: unknown policy family 'mcp'; allowed: composite, tuned, learned, rollout, mpc, "
                   "search, oracle; did you mean 'mpc'?\n")


def test_json_rows_carry_the_entry_typed(capsys):
    rows = {row["name"]: row for row in _json(capsys)}
    assert rows["rollout-solver-sparse-tuned"]["recipe"] == {"type": "RolloutPreset", "base": "solver-tuned",
                                                             "budget": "10ms", "sparse": True}
    assert rows["mpc-rates-tuned-train"]["recipe"] == {"type": "TunedLookahead", "base": "mpc-rates",
                                                       "file": "mpc-rates-suite-v1-train.json"}
    assert rows["solver"]["decisions"] == {"dispatch": "Assignment", "workforce": "Staffing",
                                           "positioning": "p-median"}
    assert (rows["oracle"]["reads_future"], rows["oracle"]["listed"]) == (True, True)
    # its measured class (what the committed frontier measured: test_policy_table checks it against frontier.csv)
    assert rows["oracle"]["budget"] == TABLE["oracle"].budget_class != "not measured"
    assert (rows["mpc-ma"]["listed"], rows["mpc-ma"]["candidate_of"], rows["mpc-ma"]["oracle_candidate"]) == \
        (False, ["v2", "v3"], True)
    assert rows["oracle-dispatch"]["oracle_candidate"] is False and rows["random"]["budget"] == "not measured"
    assert {row["family"] for row in rows.values()} == set(FAMILIES)


def test_an_unknown_policy_on_the_command_line_suggests_once_across_families(capsys):
    assert main(["evaluate", "--policy", "mpc-rate", "--scenario", "small", "--seeds", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wfbench: error: unknown policy 'mpc-rate'; available: ") and err.count("\n") == 1
    assert err.count("did you mean") == 1 and "did you mean 'mpc-rates'" in err
