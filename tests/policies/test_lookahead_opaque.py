"""The rollout under the hosted board's opaque keys scores as it does at home (issue #43), in process.

The hosted board resets a policy with ``opaque_keys(seeds)`` (an HMAC of each seed) and hands
it the world with ``set_world``; at home it gets the seeds. The rollout's sampled futures are
keyed by what it is reset with, so its actions may differ; its score must not, beyond noise.
Public seeds only (1000-1049).
"""

import numpy as np
from wfbench.policies.lookahead import Rollout

from wfbench import ScenarioConfig, policies
from wfbench.harness.isolation.sandbox import LOCAL_KEY_SECRET, opaque_keys
from wfbench.harness.runner import run_batch

CONFIG = ScenarioConfig.preset("small").replace(horizon=160)
SEEDS = [1000, 1001, 1002, 1003, 1004, 1005]


class Keyed:
    """What the sandbox's child holds: the policy, reset with the opaque keys of the seeds."""

    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self, policy):
        self.policy = policy

    def set_world(self, config):
        self.policy.set_world(config)

    def reset(self, seeds):
        self.keys = opaque_keys(np.asarray(seeds).tolist(), LOCAL_KEY_SECRET, "local")
        self.policy.reset(self.keys)

    def act(self, obs):
        return self.policy.act(obs)


def test_the_rollout_scores_within_noise_under_opaque_keys():
    home = Rollout(policies.get("solver-tuned"), K=2, H=30, R=10)
    board = Keyed(Rollout(policies.get("solver-tuned"), K=2, H=30, R=10))
    a = run_batch(home, CONFIG, SEEDS).means["nsw"]
    b = run_batch(board, CONFIG, SEEDS).means["nsw"]
    assert board.policy.config == CONFIG and home.config == CONFIG  # both got the world from the runner
    assert not np.isin(board.keys, SEEDS).any()  # the board's policy never saw a seed
    assert not np.array_equal(home.belief.H.key, board.policy.belief.H.key)  # other keys, other sampled futures
    d = b - a
    se = d.std(ddof=1) / np.sqrt(len(d))
    assert abs(d.mean()) <= max(3.0 * se, 0.01), (a, b)
    assert np.isfinite(b).all() and (b > 0).all()
