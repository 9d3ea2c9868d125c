"""The loop scaffolding the three trainers share (wfbench.train.outputs.RunOutputs), on a stand-in trainer."""

from __future__ import annotations

from contextlib import nullcontext as _no_raise
from types import SimpleNamespace

import pytest
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from wfbench.train.outputs import RunOutputs


class StandIn:
    """What RunOutputs reads of a trainer: its run record, its counter; ``save`` records what was written, and how."""

    def __init__(self, run_dir, log=False, progress=False):
        self.run = SimpleNamespace(dir=run_dir, log=log, progress=progress, global_step=0,
                                   best={"score": float("-inf"), "update": None})
        self.iteration = 0
        self.saved: list[tuple[str, bool]] = []

    def save(self, path, full=True):
        self.saved.append((str(path.relative_to(self.run.dir)), full))
        return path


def _public(score):
    return {"sample": score, "greedy": score - 0.01, "sample_workforce_cost": 20.0, "greedy_workforce_cost": 21.0,
            "seeds": [1000, 1001]}


def test_run_outputs__best_only_on_a_better_public_score_and_latest_at_the_end(tmp_path):
    t = StandIn(tmp_path)
    with RunOutputs(t, "iteration", "test", 30, 0) as out:
        for i, score in enumerate([0.70, 0.75, 0.74], start=1):
            t.iteration, t.run.global_step = i, 10 * i
            out.public(_public(score), i)
            out.checkpoint(f"iter_{i:04d}.pt")
            out.advance(10, {"sps": "1"})
    assert t.run.best["score"] == 0.75 and t.run.best["update"] == 2 and t.run.best["global_step"] == 20
    assert t.run.best["greedy"] == pytest.approx(0.74) and t.run.best["seeds"] == [1000, 1001]
    best = [s for s in t.saved if s[0] == "best.pt"]
    assert best == [("best.pt", False), ("best.pt", False)], "saved at 0.70 and 0.75, the policy only, not at 0.74"
    assert t.saved[-1] == ("latest.pt", True), "leaving the loop saves a resumable latest.pt"
    assert ("checkpoints/iter_0003.pt", True) in t.saved


def test_run_outputs__ctrl_c_saves_latest_says_how_to_resume_and_reraises(tmp_path, capsys):
    t = StandIn(tmp_path)
    with pytest.raises(KeyboardInterrupt), RunOutputs(t, "iteration", "test", 30, 0):
        t.iteration = 7
        raise KeyboardInterrupt
    assert t.saved == [("latest.pt", True)]
    out = capsys.readouterr().out
    assert "(iteration 7)" in out and f"--resume {tmp_path / 'latest.pt'}" in out


def test_run_outputs__a_failure_saves_nothing(tmp_path):
    t = StandIn(tmp_path)
    with pytest.raises(RuntimeError), RunOutputs(t, "update", "test", 30, 0):
        raise RuntimeError("broken update")
    assert t.saved == [], "a state that failed half-way is not written over latest.pt"


def test_run_outputs__tensorboard_scalars_at_the_global_step(tmp_path):
    t = StandIn(tmp_path, log=True)
    with RunOutputs(t, "update", "test", 30, 0) as out:
        t.run.global_step = 64
        out.scalars("loss", {"policy": 0.5, "value": 2.0, "kl": 0.1}, ("policy", "value", "entropy"))
        out.episodes([{"nsw": 0.7}, {"nsw": 0.8}])
        out.public(_public(0.72), 1)
    ea = EventAccumulator(str(tmp_path / "tb"))
    ea.Reload()
    tags = set(ea.Tags()["scalars"])
    assert {"loss/policy", "loss/value", "episode/nsw", "public/nsw_sample", "public/nsw_greedy"} <= tags
    assert "loss/kl" not in tags and "loss/entropy" not in tags, "only the keys asked for, where present"
    assert [(e.step, round(e.value, 6)) for e in ea.Scalars("episode/nsw")] == [(64, 0.7), (64, 0.8)]


@pytest.mark.parametrize("raised, order", [
    (None, ["cleanup", "latest.pt"]),  # the actors stop before the final save
    (KeyboardInterrupt, ["latest.pt", "cleanup"]),  # Ctrl-C: the save first, whatever stopping the actors does
    (RuntimeError, ["cleanup"]),
])
def test_run_outputs__cleanup_runs_however_the_loop_ends(tmp_path, raised, order):
    t = StandIn(tmp_path)
    events: list[str] = []
    t.save = lambda path, full=True: events.append(path.name)
    with pytest.raises(raised) if raised else _no_raise(), \
            RunOutputs(t, "iteration", "test", 30, 0, cleanup=lambda: events.append("cleanup")):
        if raised:
            raise raised
    assert events == order
