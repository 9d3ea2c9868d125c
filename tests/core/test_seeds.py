"""The named seed sets and every way of naming seeds."""

import pytest
from wfbench.leaderboard.tracks import TRACKS

from wfbench.cli import main
from wfbench.core.seeds import PUBLIC, TEST, TRAIN_START, describe, resolve_seeds, seed_set


def test_the_sets_are_disjoint_and_the_tracks_use_them():
    assert list(TEST) == list(range(50)) and list(PUBLIC) == list(range(1000, 1050)) and TRAIN_START == 1_000_000
    assert not set(TEST) & set(PUBLIC)
    for t in TRACKS.values():
        assert t.test_seeds == tuple(TEST) and t.public_seeds == tuple(PUBLIC)


@pytest.mark.parametrize("spec, expected", [
    (3, [0, 1, 2]), ("3", [0, 1, 2]), ("test", list(range(50))), ("public", list(range(1000, 1050))),
    ("public:2", [1000, 1001]), ("train:3", [1_000_000, 1_000_001, 1_000_002]), ("7-9", [7, 8, 9]),
    ("5,3, 8", [5, 3, 8]), ([4, 2], [4, 2]),
])
def test_every_spelling_resolves(spec, expected):
    assert resolve_seeds(spec) == expected


@pytest.mark.parametrize("spec, message", [
    ("nope", "seeds 'nope' not understood; allowed: a count n"), ("train", "open-ended"),
    ("public:51", r"public:51: allowed: 1..50"), ("9-7", "ends before it starts"), (0, "allowed: a count >= 1"),
    ([1, 1], "distinct"), ([-1], ">= 0"), ("public:x", "whole number"), (True, "allowed"),
])
def test_bad_seeds_name_what_is_allowed(spec, message):
    with pytest.raises(ValueError, match=message):
        resolve_seeds(spec)


def test_describe_names_the_set():
    assert describe(seed_set("public")) == "public 1000..1049 (50)"
    assert describe(seed_set("train", 4)) == "train 1000000..1000003 (4)"
    assert describe([3, 4, 5]) == "3..5 (3)" and describe([5, 1]) == "2 seeds"


def test_cli_takes_a_set_by_name_and_refuses_nonsense(capsys):
    assert main(["evaluate", "--policy", "heuristic", "--scenario", "small", "--seeds", "public:3",
                 "--backend", "serial", "--no-progress", "--format", "json"]) == 0
    assert '"seeds": [\n    1000,\n    1001,\n    1002\n  ]' in capsys.readouterr().out
    assert main(["evaluate", "--policy", "heuristic", "--scenario", "small", "--seeds", "publik"]) == 2
    assert "seeds 'publik' not understood" in capsys.readouterr().err
    assert main(["evaluate", "--policy", "heuristic", "--scenario", "small", "--seeds", "public",
                 "--seed-start", "5"]) == 2
    assert "--seed-start applies to a count" in capsys.readouterr().err
