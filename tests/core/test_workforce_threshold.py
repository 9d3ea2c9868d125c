"""The threshold workforce heuristic's rule (docs/model.md, Policies), probed through ``act``.

After a warm-up of 50 steps and at most once per 30-step cooldown: hire when the
rolling utilization (global PUR) is above 0.8, let go when it is below 0.45; the level is
drawn 0.25 / 0.5 / 0.25 (for a let-go, among the levels the mask allows).
"""

import numpy as np
import pytest

from wfbench import policies
from wfbench.core.observe import GLOBAL_FEATURES, make_obs

PUR = GLOBAL_FEATURES.index("utilization")
HIRES, LET_GOS = (1, 2, 3), (4, 5, 6)


def observation(pur, t=100, batch=1):
    """Two facilities, three idle people (one of each level), every workforce action allowed."""
    obs = make_obs(2, 4, facilities=[(1, 1, False), (5, 5, True)],
                   people=[(0, 0, 0, 0, 0), (3, 3, 3, 3, 1), (6, 6, 6, 6, 2)], t=t)
    obs = {k: np.repeat(v, batch, axis=0) for k, v in obs.items()}
    obs["globals"][:, PUR] = pur
    return obs


def threshold(seeds=(0,)):
    pol = policies.DECISIONS["workforce"]["threshold"]()
    pol.reset(list(seeds))
    return pol


def decide(pur, t=100):
    return int(threshold().act(observation(pur, t))["workforce"][0])


@pytest.mark.parametrize(("pur", "kind"), [
    (0.0, "let-go"), (0.30, "let-go"), (0.449, "let-go"), (0.451, "nothing"), (0.6, "nothing"), (0.799, "nothing"),
    (0.801, "hire"), (1.0, "hire"),
])
def test_threshold__lets_go_below_045_and_hires_above_08(pur, kind):
    a = decide(pur)
    got = "hire" if a in HIRES else "let-go" if a in LET_GOS else "nothing" if a == 0 else f"code {a}"
    assert got == kind, (f"utilization {pur}: the threshold heuristic did {got!r}, expected {kind!r} "
                         "(let go below 0.45, hire above 0.8; HP_DEFAULTS in policies/kernels/common.py)")


@pytest.mark.parametrize("pur", [0.1, 0.95])
def test_threshold__waits_out_the_50_step_warmup(pur):
    assert decide(pur, t=49) == 0, "no workforce action before step 50"
    assert decide(pur, t=50) != 0, "the warm-up ends at step 50"


def test_threshold__acts_at_most_once_per_30_step_cooldown():
    pol = threshold()
    assert pol.act(observation(0.1, t=100))["workforce"][0] in LET_GOS
    assert pol.act(observation(0.1, t=129))["workforce"][0] == 0, "step 129 is inside the 30-step cooldown"
    assert pol.act(observation(0.1, t=130))["workforce"][0] in LET_GOS, "the cooldown ends 30 steps after acting"


def test_threshold__levels_are_drawn_025_05_025():
    B = 4000
    for pur, codes in ((0.95, HIRES), (0.1, LET_GOS)):
        a = threshold(range(B)).act(observation(pur, batch=B))["workforce"]
        share = np.array([(a == c).mean() for c in codes])
        # binomial standard deviation of a share over 4000 draws: at most 0.008
        np.testing.assert_allclose(share, [0.25, 0.5, 0.25], atol=0.04,
                                   err_msg=f"level shares {share} of codes {codes} are not 0.25 / 0.5 / 0.25")


def test_threshold__lets_go_only_levels_the_mask_allows():
    B = 500
    obs = observation(0.1, batch=B)
    obs["workforce_mask"][:, 4] = 0  # no novice may be let go
    a = threshold(range(B)).act(obs)["workforce"]
    assert set(np.unique(a).tolist()) == {5, 6}, f"let-go codes {np.unique(a)}: only mids (5) and experts (6) allowed"
    obs["workforce_mask"][:, 4:] = 0
    assert (threshold(range(B)).act(obs)["workforce"] == 0).all(), "nobody may be let go: no action"
