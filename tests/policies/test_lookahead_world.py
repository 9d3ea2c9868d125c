"""The world's public parameters for a deployable policy (issue #43): ``set_world`` in process and across the sandbox.

No bubblewrap here: the sandbox's two ends are exercised in process (the child's ``serve``
over a pipe, the parent's RESET frame as it would be written).
"""

import os

import numpy as np
from wfbench.policies.lookahead import Rollout

from wfbench import ScenarioConfig, policies
from wfbench.harness.isolation import child as sandbox_child
from wfbench.harness.isolation import sandbox
from wfbench.harness.isolation.wire import Decoder, Kind, array_text, encode, text_array
from wfbench.harness.runner import public_world, run_batch
from wfbench.scenarios.resolve import resolve_scenario

SMALL = ScenarioConfig.preset("small").replace(horizon=6)


class Recorder:
    """Records what the evaluator hands it, in order; dispatches nobody, never hires."""

    decisions = ("dispatch", "workforce", "positioning")

    def __init__(self, with_world=True):
        self.calls = []
        if with_world:
            self.set_world = lambda config: self.calls.append(("set_world", config))

    def reset(self, seeds):
        self.calls.append(("reset", list(np.asarray(seeds).tolist())))

    def act(self, obs):
        B, M = obs["facilities"].shape[:2]
        N = obs["personnel"].shape[1]
        return {"dispatch": np.full((B, M), N), "workforce": np.zeros(B, dtype=np.int64),
                "positioning": np.zeros((B, 2, M))}


def test_the_runner_hands_the_public_config_before_reset_and_nothing_else():
    config = ScenarioConfig.preset("nonstationary").replace(horizon=6)  # schedules: what the observation lacks
    rec = Recorder()
    run_batch(rec, config, [3, 4])  # a user's object: through the guard
    (what, world), (what2, seeds) = rec.calls
    assert (what, what2, seeds) == ("set_world", "reset", [3, 4])
    assert world == config and world is not config and world.request_schedule == config.request_schedule
    assert set(world.to_dict()) == set(config.to_dict())  # a config: no seed, key or trace field to carry
    plain = Recorder(with_world=False)  # a policy without the hook is called as before
    run_batch(plain, config, [3])
    assert [c[0] for c in plain.calls] == ["reset"]


def test_public_world_is_a_copy_with_every_law_of_the_world():
    for name in ("paper-64", "surge-64", "clustered-64", "real-benelux"):
        config = resolve_scenario(name)
        world = public_world(config)
        assert world == config and world is not config


def test_the_world_crosses_the_sandbox_wire_with_reset():
    config = public_world(ScenarioConfig.preset("surge-64"))
    # the parent's frame: SandboxPolicy.set_world, then reset writes keys and world into RESET
    parent = object.__new__(sandbox.SandboxPolicy)
    parent.limits, parent.key_secret, parent.key_context = sandbox.Limits(), sandbox.LOCAL_KEY_SECRET, "local"
    parent._calls = {"reset": 0, "act": 0}
    sent = []
    parent._exchange = lambda frame, *a: sent.append(frame)
    parent.set_world(config)
    parent.reset([1000, 1001])
    (msg,) = Decoder().feed(sent[0])
    assert msg.kind == Kind.RESET and set(msg.arrays) == {"keys", "world"}
    assert np.array_equal(msg.arrays["keys"], sandbox.opaque_keys([1000, 1001], sandbox.LOCAL_KEY_SECRET, "local"))
    assert ScenarioConfig.from_json(array_text(msg.arrays["world"])) == config
    # the child's end: set_world before reset, then READY; a policy without set_world is only reset
    for with_world in (True, False):
        rec = Recorder(with_world)
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        os.write(to_child_w, sent[0] + encode(Kind.BYE))
        os.close(to_child_w)
        assert sandbox_child.serve(sandbox_child.Channel(to_child_r, from_child_w), rec, 512) == 0
        os.close(from_child_w)
        (reply,) = Decoder().feed(os.read(from_child_r, 1 << 16))
        os.close(to_child_r)
        os.close(from_child_r)
        assert reply.kind == Kind.READY
        assert [c[0] for c in rec.calls] == (["set_world", "reset"] if with_world else ["reset"])
        if with_world:
            assert rec.calls[0][1] == config
        assert rec.calls[-1][1] == msg.arrays["keys"].tolist()


def test_a_set_world_that_raises_is_the_policys_failure_in_one_line():
    class Bad(Recorder):
        def set_world(self, config):
            raise KeyError("grid")

    to_child_r, to_child_w = os.pipe()
    from_child_r, from_child_w = os.pipe()
    frame = encode(Kind.RESET, {"keys": np.array([7], dtype=np.int64),
                                "world": text_array(SMALL.to_json())})
    os.write(to_child_w, frame)
    os.close(to_child_w)
    assert sandbox_child.serve(sandbox_child.Channel(to_child_r, from_child_w), Bad(with_world=False), 512) == 1
    os.close(from_child_w)
    (reply,) = Decoder().feed(os.read(from_child_r, 1 << 20))
    os.close(to_child_r)
    os.close(from_child_r)
    reason = array_text(reply.arrays["reason"])
    assert reply.kind == Kind.ERROR and "in set_world" in reason and "\n" not in reason


def test_the_rollout_takes_the_evaluators_world():
    config = ScenarioConfig.preset("nonstationary").replace(horizon=4)
    roll = Rollout(policies.get("solver-tuned"), K=1, H=2, R=2)
    run_batch(roll, config, [1000])
    assert roll.config == config and roll.belief.config == config  # not the step-0 persistence model
