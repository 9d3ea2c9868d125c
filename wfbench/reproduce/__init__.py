"""Regenerate the paper's Table 2, Table 3 and Figure 3 with wfbench's model, the oracle gap, the suite, its frontier.

One module per target (:mod:`~wfbench.reproduce.table2`, :mod:`~wfbench.reproduce.table3`,
:mod:`~wfbench.reproduce.figure3`, :mod:`~wfbench.reproduce.gap`); the paper's numbers are
data (``paper.toml``, read by :mod:`~wfbench.reproduce.paper`). Each target writes markdown
and CSV (and PNG and SVG for the figures) into an output folder and returns the text it
prints. The paper's NSW is a cost (lower is better) and its formulas do not reproduce its
own numbers; ours (``docs/metrics.md``) is a welfare in [0, 1], higher is better. So the
tables put the paper's numbers beside ours and compare orderings and trends, never values;
docs/reproduction.md says what matches and why.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import wfbench.reproduce.figure3 as figure3
import wfbench.reproduce.frontier as frontier
import wfbench.reproduce.gap as gap
import wfbench.reproduce.suite as suite
import wfbench.reproduce.table2 as table2
import wfbench.reproduce.table3 as table3
import wfbench.reproduce.verify as verify
from wfbench.harness.backends import Execution
from wfbench.reproduce.common import PROCESS, Output, Progress

TARGETS = {"table2": table2.table2, "table3": table3.table3, "figure3": figure3.figure3, "gap": gap.gap,
           "suite": suite.suite, "verify": verify.verify,
           "frontier": frontier.frontier}
"""``wfbench reproduce TARGET``: each called as ``target(out, runs=, execution=, progress=)``."""

SIZES = {"table2": table2.size, "table3": table3.size, "figure3": figure3.size, "gap": gap.size, "suite": suite.size,
         "verify": lambda **_: None,  # verify: as many as the folder has pieces (a bar without a total)
         "frontier": frontier.size}


def target_size(name: str, **kwargs) -> int | None:
    """How many evaluations target ``name`` runs with these keyword arguments (for a progress bar)."""
    return SIZES[name](**kwargs)


def check_target(name: str) -> str:
    """``name`` if it is a target (:data:`TARGETS`), else ValueError naming the allowed ones."""
    if name not in TARGETS:
        raise ValueError(f"unknown target {name!r}; allowed: {', '.join(TARGETS)}")
    return name


def parse_methods(methods: str | Sequence[str] | None, target: str = "figure3",
                  what: str = "methods") -> tuple[str, ...] | None:
    """Figure 3's methods, each once in the order given, every one a policy; ValueError otherwise.

    Args:
        methods: comma-separated policy names or a sequence of them; ``None``: the default ones.
        target: the target they are for (only ``figure3`` takes methods).
        what: how the messages name the option (``"--methods"`` on the command line).

    Returns:
        The names, or ``None`` for the default.
    """
    from wfbench.policies import get

    if methods is None:
        return None
    if target != "figure3":
        raise ValueError(f"{what} applies to figure3 only, not to {target}")
    names = methods.split(",") if isinstance(methods, str) else methods
    parsed = tuple(dict.fromkeys(m.strip() for m in names if m.strip()))
    if not parsed:
        raise ValueError(f"{what}: give at least one policy name")
    for m in parsed:
        get(m)  # an unknown name fails now, not after the others ran
    return parsed


def output_folder(out: str | Path, what: str = "out") -> Path:
    """The output folder, created if missing; ValueError if it is a file or cannot be made (``what``: its name)."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {str(out)!r} exists and is not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{what} {str(out)!r}: cannot create the folder: {exc.strerror or exc}") from None
    return path


def reproduce(target: str, out: str | Path = "results", runs: int | None = 50, execution: Execution = PROCESS,
              progress: Progress = None,
              methods: str | Sequence[str] | None = None, **kwargs: Any) -> Output:
    """Regenerate one target into ``out``, as ``wfbench reproduce TARGET`` does.

    The target, Figure 3's ``methods`` (:func:`parse_methods`) and the output folder
    (:func:`output_folder`, created if missing) are checked before anything runs.

    Args:
        target: ``table2``, ``table3``, ``figure3``, ``gap`` or ``suite`` (:data:`TARGETS`).
        out: the output folder.
        runs: episodes per cell or row (``None``: frontier only, the committed frontier's seeds).
        execution: where the evaluations run (:class:`~wfbench.harness.backends.Execution`;
            default a pool of processes); the numbers do not depend on it.
        progress: called with the name of each evaluation as it starts.
        methods: figure3 only: the policies to draw (default the paper's and ours).
        **kwargs: the suite target's options (``seeds``, ``policies``, ``scenarios``, ``networks``).

    Returns:
        The :class:`Output`: the text and the files written.
    """
    check_target(target)
    parsed = parse_methods(methods, target)
    if parsed is not None:
        kwargs["methods"] = parsed
    folder = output_folder(out)
    return TARGETS[target](folder, runs=runs, execution=execution, progress=progress, **kwargs)


__all__ = ["Output", "SIZES", "TARGETS", "check_target", "output_folder", "parse_methods", "reproduce",
           "target_size"]
