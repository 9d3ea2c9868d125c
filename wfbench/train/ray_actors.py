"""The IMPALA trainer's actors as Ray actors (``ImpalaConfig.address`` set): the learner's side of the plumbing.

Imported only by :meth:`wfbench.train.impala.Trainer.train` when ``address`` is set, so Ray stays
an optional dependency (the ``ray`` extra). The learner stays in this process and publishes its
parameters with ``ray.put``; each :class:`~wfbench.train.impala.RemoteActor` runs an
:class:`~wfbench.train.impala.Actor` with its own Simulator on its share of the training seeds and
has one rollout in flight, so the lag depends on timing and the run is not deterministic.
``address="local"`` starts (and shuts down) a Ray instance; ``"auto"`` or ``"ray://HOST:PORT"``
join a cluster, whose every node must import this version of wfbench. What travels where, the
schedule and the end of a run: ``docs/impala.md``, "Ray: actors on a cluster".
"""

from __future__ import annotations

import os

import ray

from wfbench.harness.backends import join_ray


class RayActors:
    """``cfg.ray_actors`` Ray actors of class ``actor_cls``, one rollout in flight each, fed the newest parameters.

    Args:
        cfg: the run's ``ImpalaConfig`` (``address``, ``ray_actors``, ``threads``).
        actor_cls: the plain class to run as a Ray actor, built as ``actor_cls(cfg, index, meta, *args)``,
            with methods ``ready()`` and ``rollout(version, params)`` (``impala.RemoteActor``).
        metas: each actor's resume state, or None for a fresh actor.
        version: the learner update of ``params``.
        params: the learner's parameters (a CPU state_dict) that the actors start with.
        args: more arguments of every actor (IMPALA's: the run's scenario, resolved once by the learner),
            pickled to each.
    """

    def __init__(self, cfg, actor_cls, metas: list, version: int, params: dict, args: tuple = ()):
        self.owns = not ray.is_initialized()  # True: this object started Ray (or connected) and shuts it down
        if self.owns and cfg.address == "local":
            ray.init(
                address="local",
                num_cpus=max(os.cpu_count() or 1, cfg.ray_actors * cfg.threads),
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
        elif self.owns:
            join_ray(cfg.address, log_to_driver=False, configure_logging=False)  # one line where no cluster answers
        self.actors: list = []
        self.pending: dict = {}  # ObjectRef of a rollout in flight -> the index of its actor
        self.remaining = 0  # rollouts still to ask for
        try:
            remote = ray.remote(num_cpus=cfg.threads)(actor_cls)
            self.actors = [remote.remote(cfg, i, meta, *args) for i, meta in enumerate(metas)]
            for i, ref in enumerate([a.ready.remote() for a in self.actors]):
                self._get(ref, i)  # a worker that cannot import wfbench or build its simulator fails here
            self.publish(version, params)
        except BaseException:
            self.close()
            raise

    def publish(self, version: int, params: dict) -> None:
        """The parameters that the next rollouts asked for act with (CPU tensors: actors may be on other nodes)."""
        self.version, self.params = version, ray.put({k: v.cpu() for k, v in params.items()})

    def run(self, count: int) -> None:
        """Ask for ``count`` rollouts in all: one to each actor now, the others as rollouts come in."""
        self.remaining = count
        for i in range(min(count, len(self.actors))):
            self._ask(i)

    def _ask(self, i: int) -> None:
        # the ObjectRef as an argument: Ray hands the actor the state_dict itself
        self.pending[self.actors[i].rollout.remote(self.version, self.params)] = i
        self.remaining -= 1

    def next(self) -> dict:
        """The first rollout to finish; its actor is asked for the next one at once (while the learner learns)."""
        [ref], _ = ray.wait(list(self.pending), num_returns=1)
        i = self.pending.pop(ref)
        roll = self._get(ref, i)
        if self.remaining > 0:
            self._ask(i)
        return roll

    def _get(self, ref, i: int):
        try:
            return ray.get(ref)
        except ray.exceptions.RayTaskError as exc:  # the actor's own exception, with the remote trace in its message
            raise RuntimeError(f"Ray actor {i} failed: {exc.cause!r}") from exc.cause
        except ray.exceptions.RayActorError as exc:
            raise RuntimeError(f"Ray actor {i} died: {exc}") from None

    def close(self) -> None:
        """Kill the actors (rollouts in flight are dropped); shut Ray down or disconnect if this object started it."""
        for actor in self.actors:
            ray.kill(actor)
        self.actors, self.pending = [], {}
        if self.owns and ray.is_initialized():
            ray.shutdown()
