"""The one reading of a policy spec (wfbench.policies.registry.parse_spec), and those who read specs through it."""

from __future__ import annotations

import pytest
from wfbench.policies.registry import CHECKPOINT_DIR, LINEUPS, get, parse_member, parse_spec
from wfbench.policies.tuned import TUNED_DIR

# spec -> (kind, name, path, seed, mode, algo, attr, parts)
TABLE = [
    ("heuristic", "composite", "heuristic", "", None, None, "", "", ()),
    ("oracle", "oracle", "oracle", "", None, None, "", "", ()),
    ("heuristic-tuned", "tuned", "heuristic-tuned", str(TUNED_DIR / "heuristic-paper-64.json"), None, None, "", "",
     ()),
    ("mpc-ma-tuned-train", "lookahead", "mpc-ma-tuned-train", str(TUNED_DIR / "mpc-ma-suite-v1-train.json"), None,
     None, "", "", ()),
    ("mpc-ma", "lookahead", "mpc-ma", "", None, None, "", "", ()),
    ("oracle-planner", "composite", "oracle-planner", "", None, None, "", "", ()),
    ("ppo-joint", "learned", "ppo-joint", str(CHECKPOINT_DIR / "ppo-joint-paper-64.pt"), None, None, "", "", ()),
    ("ppo-joint@greedy", "learned", "ppo-joint", str(CHECKPOINT_DIR / "ppo-joint-paper-64.pt"), None, "greedy", "",
     "", ()),
    ("ppo-general#seed3", "member", "ppo-general", "", 3, None, "", "", ()),
    ("ppo-general#seed3@greedy", "member", "ppo-general", "", 3, "greedy", "", "", ()),
    ("ppo-general#seedx", "member", "ppo-general", "", -1, None, "", "", ()),
    ("ppo:runs/x/best.pt", "checkpoint", "ppo", "runs/x/best.pt", None, None, "ppo", "", ()),
    ("impala:a@b/c.pt@greedy", "checkpoint", "impala", "a@b/c.pt", None, "greedy", "impala", "", ()),
    ("hindsight:", "checkpoint", "hindsight", "", None, None, "hindsight", "", ()),
    ("tuned:my/file", "tuned-file", "", "my/file", None, None, "", "", ()),
    ("runs/t.JSON", "tuned-file", "", "runs/t.JSON", None, None, "", "", ()),
    ("ppo:x.json", "checkpoint", "ppo", "x.json", None, None, "ppo", "", ()),
    ("nearest+threshold+spatial", "parts", "nearest+threshold+spatial", "", None, None, "", "",
     ("nearest", "threshold", "spatial")),
    ("a+b", "parts", "a+b", "", None, None, "", "", ("a", "b")),
    ("my_pkg.mod:make.policy", "entry-point", "my_pkg.mod", "", None, None, "", "make.policy", ()),
    ("pkg:a+b", "entry-point", "pkg", "", None, None, "", "a+b", ()),
    ("nope@greedy", "unknown", "nope", "", None, "greedy", "", "", ()),
]


@pytest.mark.parametrize(("spec", "kind", "name", "path", "seed", "mode", "algo", "attr", "parts"), TABLE)
def test_parse_spec__each_form_reads_as_one_kind(spec, kind, name, path, seed, mode, algo, attr, parts):
    p = parse_spec(spec)
    assert (p.text, p.kind, p.name, p.path, p.seed, p.mode, p.algo, p.attr, p.parts) == \
        (spec, kind, name, path, seed, mode, algo, attr, parts)


def test_parse_spec__members_read_through_it():
    assert parse_member("ppo-general#seed2@greedy") == ("ppo-general", 2, "greedy")
    assert parse_member("ppo-general#seed2") == ("ppo-general", 2, "")
    assert parse_member("ppo-general") is None and parse_member("ppo:x#seed1") is None


@pytest.mark.parametrize(("spec", "message"), [
    ("nope", "unknown policy 'nope'; available: "),
    ("ppo:", "policy 'ppo:': give a checkpoint path, e.g. ppo:runs/ppo/best.pt"),
    ("a+b", "composite 'a+b' needs three names, dispatch+workforce+positioning"),
    ("no_such_module_xyz:p", "cannot import module 'no_such_module_xyz' of policy entry point"),
    ("wfbench.policies:nothing_here", "module 'wfbench.policies' has no attribute 'nothing_here'"),
    ("ppo-general#seed99", "policy 'ppo-general#seed99': 'ppo-general' has training seeds 0-4"),
])
def test_get__refuses_each_form_in_one_line(spec, message):
    with pytest.raises(ValueError) as info:
        get(spec)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_lineups__each_names_registered_policies_once():
    for lineup, members in LINEUPS.items():
        assert len(set(members)) == len(members), lineup
        assert all(parse_spec(m).kind in ("composite", "oracle", "tuned") for m in members), lineup


def test_fingerprint_and_budget_read_the_spec_as_the_registry_does():
    from wfbench.leaderboard.submit import is_entry_point, policy_fingerprint

    from wfbench.harness.budget import policy_budget

    assert is_entry_point("my_pkg.mod:policy") and not is_entry_point("ppo:x.pt") and not is_entry_point("t.json")
    assert policy_fingerprint("heuristic-tuned")[1]["kind"] == "builtin"
    assert "file" in policy_fingerprint("heuristic-tuned")[1]
    assert policy_budget("heuristic-tuned")["kind"] == "tuned"
    assert policy_budget("heuristic")["kind"] == "builtin" and policy_budget("pkg:x")["kind"] == "other"
