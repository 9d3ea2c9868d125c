"""Built-ins under opaque keys (issue 42, board problem 6): which score as ``wfbench evaluate`` does, bit for bit.

The hosted board and ``wfbench evaluate --sandbox`` hand a policy's ``reset`` one opaque key
per episode (HMAC of the seed, :func:`wfbench.harness.isolation.sandbox.opaque_keys`) instead of the
seed. A built-in whose decisions draw from a stream keyed by the number ``reset`` gets
therefore plays other draws under keys than under seeds: same world, other hires' levels,
other noise. These tests run each deployable built-in in-process, once with its seeds (as
``wfbench evaluate`` runs it) and once with the keys of the local sandbox and of two fresh
boards with different secrets, and compare the per-seed rows bit for bit.

:data:`KEY_DEPENDENT` is the list docs/leaderboard.md gives (under `wfbench serve seed`):
a built-in in it must differ under keys (and stay reproducible on one board); every other
one must give the rows of its seeds on every board. A built-in whose randomness comes to
be drawn from the episode itself leaves the list, and the docs' paragraph with it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from wfbench.leaderboard.board.hidden import key_context
from wfbench.policies import get
from wfbench.policies.registry import deployable_names, learned_names

from wfbench.core.config import ScenarioConfig
from wfbench.harness.budget import results_only
from wfbench.harness.evaluation import evaluate
from wfbench.harness.isolation.sandbox import LOCAL_KEY_CONTEXT, LOCAL_KEY_SECRET, opaque_keys

SCENARIO = ScenarioConfig.preset("small")  # the whole horizon: the threshold rule hires and lets go after step 50
SEEDS = [0, 1, 2, 3]
# the local sandbox's keys and two fresh boards' (fixed secrets, so that the test is the same every run)
BOARDS = {
    "local": (LOCAL_KEY_SECRET, LOCAL_KEY_CONTEXT),
    "board-1": (b"fresh-board-1-secret", key_context("paper-64", "dev")),
    "board-2": (b"fresh-board-2-secret", key_context("paper-64", "test")),
}

# The built-ins whose decisions depend on the number reset gets: the threshold and staffing rules draw the level
# of each hire and let-go, the stochastic and random rules their noise, the networks their sampled actions, each
# from a stream keyed by that number (wfbench.policies.protocol.decision_key, NetworkPolicy.reset).
KEY_DEPENDENT = frozenset({
    "random", "heuristic", "heuristic-stochastic", "random-dispatch", "random-positioning",
    "solver", "solver-dispatch", "solver-workforce", "solver-positioning", "solver-sparse",
    "heuristic-tuned", "solver-tuned", "heuristic-tuned-train", "solver-tuned-train",
    *learned_names(),
})
# composites of decisions that draw nothing: they must score the same under any keys
DETERMINISTIC = ("nearest+fixed+none", "nearest+fixed+spatial", "assignment+fixed+facility-location")


class Keyed:
    """``inner`` as the sandbox's child runs it: its ``reset`` gets the board's opaque keys instead of the seeds."""

    def __init__(self, inner, secret: bytes, context: str):
        self.inner, self.secret, self.context = inner, secret, context
        self.decisions = inner.decisions
        self.name = getattr(inner, "name", type(inner).__name__)
        self.handed: list[int] = []

    def reset(self, seeds) -> None:
        keys = opaque_keys(np.asarray(seeds).tolist(), self.secret, self.context)
        self.handed = keys.tolist()
        self.inner.reset(keys)

    def act(self, obs):
        return self.inner.act(obs)


def _rows(policy) -> pd.DataFrame:
    return results_only(evaluate(policy, SCENARIO, SEEDS, act_timeout_s=None))


def _keyed(name: str, board: str) -> tuple[pd.DataFrame, Keyed]:
    policy = Keyed(get(name), *BOARDS[board])
    return _rows(policy), policy


def _same(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    return list(a.columns) == list(b.columns) and a.equals(b)


def _case(name: str):
    return pytest.param(name, marks=pytest.mark.slow) if name in learned_names() else name


def test_the_list_names_only_deployable_builtins():
    assert KEY_DEPENDENT <= set(deployable_names())


@pytest.mark.parametrize("name", [_case(n) for n in deployable_names()])
def test_builtin_under_keys_scores_as_documented(name):
    plain = _rows(name)
    for board in BOARDS:
        keyed, policy = _keyed(name, board)
        assert not set(policy.handed) & set(SEEDS)  # it really was handed keys, not seeds
        if name in KEY_DEPENDENT:
            assert not _same(plain, keyed), (
                f"{name} scores under {board}'s keys as under the seeds: its randomness no longer comes from the "
                f"number reset gets; take it off KEY_DEPENDENT and docs/leaderboard.md's list")
            again, _ = _keyed(name, board)
            assert _same(keyed, again), f"{name}: one board's keys must give the same rows every time"
        else:
            pd.testing.assert_frame_equal(keyed, plain, check_exact=True, obj=f"{name} under {board}'s keys")


@pytest.mark.parametrize("name", DETERMINISTIC)
def test_composites_that_draw_nothing_score_as_evaluate_on_every_board(name):
    plain = _rows(name)
    for board in BOARDS:
        keyed, _ = _keyed(name, board)
        pd.testing.assert_frame_equal(keyed, plain, check_exact=True, obj=f"{name} under {board}'s keys")


def test_a_key_dependent_builtin_differs_between_boards():
    """Two boards with different secrets hand other keys, so a stochastic built-in's rows differ between them."""
    a, _ = _keyed("heuristic", "board-1")
    b, _ = _keyed("heuristic", "board-2")
    assert not _same(a, b)
