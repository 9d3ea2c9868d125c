"""What the trainers' loops write besides learning: TensorBoard, the progress bar, ``best.pt``, Ctrl-C.

:class:`RunOutputs` is the loop's scaffolding in one place (``docs/rl.md``, "The trainers").
"""

from __future__ import annotations

from collections.abc import Callable

from wfbench.core.kpis import SCORE
from wfbench.train.scoring import log_public


class RunOutputs:
    """What the three trainers' loops write besides learning: the loop's scaffolding in one place.

    ``with RunOutputs(trainer, unit, desc, total, initial) as out:`` opens the TensorBoard
    writer (``RUN/tb``, when ``trainer.run.log``) and the progress bar (when ``trainer.run.progress``;
    ``initial`` of ``total`` environment steps done). Inside, the loop calls
    :meth:`scalars`, :meth:`public` (after scoring the public seeds: logs the score and keeps
    ``best.pt``), :meth:`checkpoint` and :meth:`advance`. Leaving the block saves
    ``latest.pt``; Ctrl-C saves it too, says how to resume and re-raises. ``unit`` names the
    trainer's counter attribute (``"update"`` or ``"iteration"``) for that message.
    ``cleanup`` (IMPALA: stop the actors) runs however the block is left: after the save
    on Ctrl-C, before it on a normal exit, so neither waits on the other going wrong.
    """

    def __init__(self, trainer, unit: str, desc: str, total: int, initial: int,
                 cleanup: Callable[[], None] | None = None):
        self.trainer, self.unit, self.cleanup = trainer, unit, cleanup
        self.writer = self.bar = None
        self.last_nsw: float | None = None  # of the last finished training episode, shown on the bar
        if trainer.run.log:
            from torch.utils.tensorboard import SummaryWriter

            self.writer = SummaryWriter(str(trainer.run.dir / "tb"))
        if trainer.run.progress:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="step", unit_scale=True, desc=desc)

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        t = self.trainer
        latest = t.run.dir / "latest.pt"
        try:
            if exc_type is KeyboardInterrupt:
                t.save(latest)
                if self.bar:
                    self.bar.close()
                print(f"interrupted: checkpoint saved to {latest} ({self.unit} {getattr(t, self.unit)}); "
                      f"continue with --resume {latest}")
        finally:
            try:
                if self.cleanup:
                    self.cleanup()
            finally:
                if self.writer:
                    self.writer.close()
        if exc_type is None:
            if self.bar:
                self.bar.close()
            t.save(latest)

    def scalars(self, prefix: str, values: dict, keys=None) -> None:
        """TensorBoard ``prefix/key`` for each of ``keys`` (default: all) present in ``values``, at the global step."""
        if self.writer:
            for k in values if keys is None else [k for k in keys if k in values]:
                self.writer.add_scalar(f"{prefix}/{k}", values[k], self.trainer.run.global_step)

    def episodes(self, episodes: list[dict]) -> None:
        """The finished training episodes' KPIs (``episode/*``)."""
        for ep in episodes:
            self.scalars("episode", ep)
            self.last_nsw = ep[SCORE]

    def public(self, res: dict, count: int) -> None:
        """Log a public score (:func:`wfbench.train.scoring.score_public`); keep ``best.pt`` when it is the best.

        Best: the score of the result's ``select`` mode (the sampled one unless the trainer
        selects greedy) above the run's best so far; ``best.pt`` holds the policy only.
        """
        t, run = self.trainer, self.trainer.run
        if self.writer:
            log_public(self.writer, res, run.global_step)
        mode = res.get("select", "sample")
        if res[mode] > run.best["score"]:
            run.best = {"score": res[mode], "update": count, "global_step": run.global_step, "mode": mode,
                        "seeds": res["seeds"], "greedy": res["greedy"]}
            t.save(run.dir / "best.pt", full=False)

    def after_update(self, count: int) -> None:
        """PPO's and IMPALA's end of update ``count``: evaluation and checkpoints when they are due.

        Every ``eval_every`` updates score the public seeds (a history row, ``best.pt``),
        every ``checkpoint_every`` save ``checkpoints/update_<count>.pt`` and ``latest.pt``.
        """
        t, run = self.trainer, self.trainer.run
        if run.config.eval_every and count % run.config.eval_every == 0:
            res = t.evaluate_public()
            run.history.append({"update": count, "global_step": run.global_step, **res})
            self.public(res, count)
        if count % run.config.checkpoint_every == 0:
            self.checkpoint(f"update_{count:06d}.pt")

    def checkpoint(self, name: str) -> None:
        """``checkpoints/NAME`` and ``latest.pt``, both resumable."""
        self.trainer.save(self.trainer.run.dir / "checkpoints" / name)
        self.trainer.save(self.trainer.run.dir / "latest.pt")

    def advance(self, steps: int, postfix: dict) -> None:
        """Move the progress bar by ``steps``; ``postfix``, the last training episode's NSW, the best public score."""
        if self.bar:
            self.bar.update(steps)
            postfix = dict(postfix)
            if self.last_nsw is not None:
                postfix["ep_nsw"] = f"{self.last_nsw:.3f}"
            if self.trainer.run.best["update"] is not None:
                postfix["public"] = f"{self.trainer.run.best['score']:.3f}"
            self.bar.set_postfix(postfix)
