"""wfbench.testing.check_policy: the built-in policies pass; each way of breaking the protocol is named in one line."""

from __future__ import annotations

import numpy as np
import pytest

from wfbench.testing import PolicyCheckError, check_policy

SEEDS = (0, 1, 2)
M = N = 8  # the small scenario's slots


class Dispatch:
    """Nobody sent anywhere; the subclasses break one rule each."""

    decisions = ("dispatch",)

    def reset(self, seeds):
        self.B = len(seeds)

    def act(self, obs):
        return {"dispatch": np.full((self.B, M), N)}


class ExtraKey(Dispatch):
    def act(self, obs):
        return {**super().act(obs), "workforce": np.zeros(self.B, dtype=np.int64)}


class WrongShape(Dispatch):
    def act(self, obs):
        return {"dispatch": np.full((self.B, M + 1), N)}


class Strings(Dispatch):
    def act(self, obs):
        return {"dispatch": np.full((self.B, M), "x")}


class IgnoresTheMask(Dispatch):
    def act(self, obs):
        return {"dispatch": np.zeros((self.B, M), dtype=np.int64)}  # person 0 to every facility, requesting or not


class GlobalRandom(Dispatch):
    """Draws from one generator that reset never starts over."""

    rng = np.random.default_rng(0)

    def act(self, obs):
        allowed = obs["dispatch_mask"][..., :-1].any(axis=2)
        first = obs["dispatch_mask"][..., :-1].argmax(axis=2)
        pick = allowed & (self.rng.random(allowed.shape) < 0.5)
        return {"dispatch": np.where(pick, first, obs["dispatch_mask"].shape[2] - 1)}


class SeededRandom(Dispatch):
    """GlobalRandom with one generator per environment, keyed by its seed (docs/policies.md#batches-and-seeds)."""

    def reset(self, seeds):
        self.rngs = [np.random.default_rng([int(s), 42]) for s in seeds]

    def act(self, obs):
        allowed = obs["dispatch_mask"][..., :-1].any(axis=2)
        first = obs["dispatch_mask"][..., :-1].argmax(axis=2)
        coins = np.stack([rng.random(allowed.shape[1]) for rng in self.rngs])
        return {"dispatch": np.where(allowed & (coins < 0.5), first, obs["dispatch_mask"].shape[2] - 1)}


class PlaceKeyed(GlobalRandom):
    """One generator per place in the batch, started over in reset: repeats, but not alone."""

    def reset(self, seeds):
        super().reset(seeds)
        self.rng = np.random.default_rng(len(seeds))


class LetsGoExperts:
    decisions = ("workforce",)

    def reset(self, seeds):
        self.B = len(seeds)

    def act(self, obs):
        return {"workforce": np.full(self.B, 6)}  # let an expert go, every step


class NoAct:
    decisions = ("dispatch",)

    def reset(self, seeds):
        pass


class ListDecisions(Dispatch):
    decisions = ["dispatch"]


@pytest.mark.parametrize("policy", ["heuristic", "random", "nearest+threshold+spatial"])
def test_built_in_policies_pass(policy):
    check_policy(policy, "small", SEEDS)


def test_a_partial_policy_keyed_by_its_seeds_passes():
    check_policy(SeededRandom(), "small", SEEDS)
    check_policy(SeededRandom(), "paper-64", [5], steps=20)


@pytest.mark.parametrize(("policy", "message"), [
    (NoAct(), "policy 'NoAct' does not follow the policy protocol: it lacks act; a policy has decisions, reset(seeds) "
              "and act(obs) (docs/policies.md#the-protocol)"),
    (ListDecisions(), "policy 'ListDecisions' has decisions = ['dispatch']; allowed: a tuple of distinct names out of "
                      "('dispatch', 'workforce', 'positioning')"),
    (ExtraKey(), "policy 'ExtraKey' at step 0 returned the keys ['dispatch', 'workforce'] from act; allowed: exactly "
                 "its decisions ['dispatch']"),
    (WrongShape(), "policy 'WrongShape' at step 0 returned a malformed action: dispatch action has shape (3, 9), "
                   "expected (3, 8)"),
    (Strings(), "policy 'Strings' at step 0 returned a malformed action: dispatch action has dtype <U1; allowed: "
                "integers"),
    (IgnoresTheMask(), "policy 'IgnoresTheMask' at step 0 sends person 0 to facility slot 0 in the environment of "
                       "seed 0, which dispatch_mask forbids; allowed: a person p with dispatch_mask[b, f, p] = 1, or "
                       "8 (nobody)"),
    (LetsGoExperts(), "policy 'LetsGoExperts' at step 1 chooses workforce action 6 in the environment of seed 1, "
                      "which workforce_mask forbids; allowed: an action a with workforce_mask[b, a] = 1 (0, the "
                      "no-op, always is)"),
])
def test_each_broken_rule_is_named_in_one_line(policy, message):
    with pytest.raises(PolicyCheckError) as err:
        check_policy(policy, "small", SEEDS)
    assert str(err.value) == message


def test_actions_that_do_not_repeat_for_the_same_seeds_are_named():
    with pytest.raises(PolicyCheckError, match=r"^policy 'GlobalRandom' gave different dispatch actions at step \d+ "
                                               r"in the environment of seed \d when reset with the same seeds again; "
                                               r"allowed: the same actions for the same seed \(start the policy's "
                                               r"randomness over in reset\(seeds\), keyed by each environment's "
                                               r"seed, never by its place in the batch\)$"):
        check_policy(GlobalRandom(), "small", SEEDS)


def test_randomness_keyed_by_the_place_in_the_batch_is_named():
    with pytest.raises(PolicyCheckError, match=r"^policy 'PlaceKeyed' gave different dispatch actions at step \d+ in "
                                               r"the environment of seed 2 alone and in the batch \[0, 1, 2\]; "
                                               r"allowed: the same actions for the same seed "):
        check_policy(PlaceKeyed(), "small", SEEDS)


def test_masks_false_lets_a_forbidden_choice_through():
    check_policy(IgnoresTheMask(), "small", SEEDS, steps=5, masks=False)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match=r"^seeds=\[-1\] is not allowed; allowed: one or more integers >= 0$"):
        check_policy("heuristic", seeds=[-1])
    with pytest.raises(ValueError, match=r"^steps=0 is not allowed; allowed: 1\.\.200 \(the horizon\), or None$"):
        check_policy("heuristic", steps=0)
