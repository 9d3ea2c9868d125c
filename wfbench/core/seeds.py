"""Named seed sets: every seed range has one purpose, defined here and nowhere else.

- ``test`` (0-49): the seeds of every reported number (tables, leaderboard rankings).
- ``public`` (1000-1049): development, tuning and checkpoint selection.
- ``train`` (1,000,000 and up): RL training episodes; never evaluated on.

Tuning or selecting on ``test`` makes the reported numbers worthless, so anything that
tunes or selects (``wfbench tune``, the RL trainers' checkpoint choice) uses ``public``
and records the seeds it used. Wherever seeds are accepted (``--seeds`` on the command
line, ``seeds=`` in Python) a set is accepted by name; see :func:`resolve_seeds`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

TEST = range(0, 50)
PUBLIC = range(1000, 1050)
TRAIN_START = 1_000_000
SEED_SETS: dict[str, range] = {
    "test": TEST,
    "public": PUBLIC,
    "train": range(TRAIN_START, 2**31 - 1),
}
SPEC_HELP = ("a count n (seeds 0..n-1), a set name (test = 0-49, public = 1000-1049, train = 1000000 and up; "
             "'public:10' for its first 10, 'train:N' for N training seeds), a range 'a-b' (inclusive) or a "
             "comma-separated list")


def seed_set(name: str, n: int | None = None) -> list[int]:
    """The first ``n`` seeds of the set ``name`` (all of it when ``n`` is None; ``train`` needs ``n``)."""
    if name not in SEED_SETS:
        raise ValueError(f"unknown seed set {name!r}; allowed: {', '.join(SEED_SETS)}")
    full = SEED_SETS[name]
    if n is None:
        if name == "train":
            raise ValueError("the train set is open-ended: say how many, e.g. 'train:1000'")
        return list(full)
    if not 1 <= n <= len(full):
        raise ValueError(f"{name}:{n}: allowed: 1..{len(full)} seeds of the {name} set")
    return list(full[:n])


def _parse(spec: str) -> list[int]:
    text = spec.strip()
    name, _, count = text.partition(":")
    if name in SEED_SETS:
        if count and not count.isdigit():
            raise ValueError(f"seeds {spec!r}: the count after ':' must be a whole number")
        return seed_set(name, int(count) if count else None)
    try:
        if text.isdigit():
            return resolve_seeds(int(text))
        if "," in text:
            return [int(s) for s in text.split(",") if s.strip()]
        lo, sep, hi = text.partition("-")
        if sep and lo.strip().isdigit() and hi.strip().isdigit():
            if int(hi) < int(lo):
                raise ValueError(f"seeds {spec!r}: the range ends before it starts")
            return list(range(int(lo), int(hi) + 1))
    except ValueError as exc:
        if "range ends" in str(exc) or "allowed" in str(exc):
            raise
    raise ValueError(f"seeds {spec!r} not understood; allowed: {SPEC_HELP}")


def resolve_seeds(seeds: int | str | Iterable[int]) -> list[int]:
    """The seed list a ``seeds`` argument names.

    Args:
        seeds: a count ``n`` (seeds ``0..n-1``), a string (a set name such as
            ``"public"``, ``"train:1000"``, ``"0-49"``, ``"3,5,7"`` or ``"50"``), or a
            sequence of distinct integers >= 0.

    Raises:
        ValueError: naming what is wrong and what is allowed.
    """
    if isinstance(seeds, bool):
        raise ValueError(f"seeds = {seeds}: allowed: {SPEC_HELP}")
    if isinstance(seeds, (int, np.integer)):
        if seeds < 1:
            raise ValueError(f"seeds = {seeds}: allowed: a count >= 1, or {SPEC_HELP}")
        return list(range(int(seeds)))
    out = _parse(seeds) if isinstance(seeds, str) else [int(s) for s in seeds]
    if not out:
        raise ValueError(f"seeds is empty; allowed: {SPEC_HELP}")
    if any(s < 0 for s in out):
        raise ValueError(f"seeds must be >= 0, got {min(out)}")
    if len(set(out)) != len(out):
        raise ValueError("seeds must be distinct")
    return out


def describe(seeds: list[int]) -> str:
    """A short name for a seed list: the set it is (``public 1000..1049``), else its range or count."""
    for name, full in SEED_SETS.items():
        if seeds and seeds == list(full[: len(seeds)]) and (name == "train" or len(seeds) == len(full)):
            return f"{name} {seeds[0]}..{seeds[-1]} ({len(seeds)})"
    if seeds == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}..{seeds[-1]} ({len(seeds)})"
    return f"{len(seeds)} seeds"
