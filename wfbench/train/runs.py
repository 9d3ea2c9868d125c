"""A training run from its settings, the same from Python and from ``wfbench train``: :func:`fit`.

:func:`fit` takes an algorithm's name and its config's settings, names the run folder when none
is given (``runs/ALGO-VARIANT-SCENARIO``), checks a resumed run against its checkpoint, trains,
and leaves ``best.pt`` after every run (the last weights when no evaluation ran:
:func:`wfbench.train.checkpoints.save_unselected_best`). ``wfbench train`` is a shell over it, so
both write the same files. This module imports no torch until :func:`fit` runs (``wfbench
--help`` stays fast). ``docs/rl.md``, "The command line".
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from wfbench.train.registry import DEFAULT_ALGORITHM, get_algorithm

# what a resumed run may change of its settings: how long it goes on, and where and on what it runs
RESUME_MAY_CHANGE = ("steps", "run_dir", "device", "threads", "address", "procs")


class SettingsError(ValueError):
    """A setting, or a checkpoint to resume, that :func:`fit` refuses before training starts (one line)."""


def resumed_algorithm(resume: str | Path, algo: str | None = None) -> str:
    """The algorithm of the run that checkpoint ``resume`` continues.

    Raises:
        ValueError: the checkpoint cannot be read, holds no optimizer state (a ``best.pt``)
            or is a run of another algorithm than ``algo`` (when given).
    """
    from wfbench.policies.neural.policy import load_checkpoint

    return _resumed(load_checkpoint(resume), resume, algo)


def _resumed(saved: dict, resume: str | Path, algo: str | None) -> str:
    if "optimizer" not in saved:
        raise ValueError(f"checkpoint {str(resume)!r} has no optimizer state (a best.pt?): resume from "
                         "latest.pt or a checkpoints/update_*.pt")
    run_algo = saved.get("algo", DEFAULT_ALGORITHM)
    if algo is not None and algo != run_algo:
        raise ValueError(f"checkpoint {str(resume)!r} is a {run_algo} run, not --algo {algo}")
    return run_algo


def fit(algo: str | None = None, *, resume: str | Path | None = None, progress: bool = True, log: bool = True,
        **settings: Any):
    """Train a run of ``algo`` with ``settings``; returns its trainer, trained.

    Args:
        algo: an algorithm of :data:`wfbench.train.registry.ALGORITHMS` (default: ppo, or the
            algorithm of the checkpoint ``resume`` continues).
        resume: a full checkpoint of a run (``latest.pt`` or ``checkpoints/*``) to continue.
            The run keeps its settings: of ``settings`` only those of
            :data:`RESUME_MAY_CHANGE` may differ from them (``steps`` may raise the total).
        progress: show a progress bar.
        log: write TensorBoard logs (``RUN/tb``).
        **settings: fields of the algorithm's config, e.g. ``scenario="small"``,
            ``steps=100_000``, ``model="tiny"``. Without ``run_dir`` the run goes to
            ``runs/ALGO-VARIANT-SCENARIO`` (``:`` and ``,`` of the scenario spelled ``-`` and ``+``).

    Returns:
        The trainer after training: its ``run`` record holds the folder, the best public
        score and the steps taken. The folder holds ``config.json``, ``latest.pt``,
        ``best.pt`` (always: the last weights, marked not selected, when no evaluation ran)
        and ``checkpoints/``.

    Raises:
        SettingsError: a setting the algorithm does not have or does not allow, or a
            checkpoint that cannot be resumed with these settings; nothing is trained.
    """
    from wfbench.train.checkpoints import save_unselected_best

    try:
        config, algorithm = _config(algo, resume, settings)
        trainer = algorithm.trainer_class()(config, resume=resume, progress=progress, log=log)
    except (ValueError, TypeError) as exc:
        raise SettingsError(str(exc)) from exc
    trainer.train()
    save_unselected_best(trainer)  # best.pt after every run: the last weights when no evaluation chose one
    return trainer


def _config(algo: str | None, resume: str | Path | None, settings: dict):
    """The config of the run and its algorithm: ``settings`` over the defaults, or over a resumed run's own."""
    from wfbench.policies.neural.policy import load_checkpoint

    saved = None
    if resume is not None:
        saved = load_checkpoint(resume)
        algo = _resumed(saved, resume, algo)
    name = algo or DEFAULT_ALGORITHM
    algorithm = get_algorithm(name)
    config_cls = algorithm.config_class()
    names = [f.name for f in dataclasses.fields(config_cls)]
    unknown = [k for k in settings if k not in names]
    if unknown:
        raise ValueError(f"{name} has no setting {', '.join(map(repr, unknown))}; allowed: {', '.join(names)}")
    if saved is not None:
        kept = saved["train_config"]
        changed = sorted(k for k in settings if k not in RESUME_MAY_CHANGE and settings[k] != kept.get(k))
        if changed:
            raise ValueError(f"--resume keeps the run's settings; these differ from it: {', '.join(changed)}")
        return config_cls.from_dict({**kept, **settings}), algorithm
    given = dict(settings)
    where = given.get("scenarios", given.get("scenario", config_cls.scenario)).replace(":", "-").replace(",", "+")
    given.setdefault("run_dir", str(Path("runs") / f"{name}-{given.get('variant', config_cls.variant)}-{where}"))
    return config_cls(**given), algorithm
