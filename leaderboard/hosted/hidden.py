"""The two phases of a hosted track: development on the public seeds, test on hidden seeds held by the server.

- ``dev``: the track's public seeds (1000-1049, :data:`wfbench.core.seeds.PUBLIC`); the
  submission's log and per-seed rows are shown.
- ``test``: :data:`DEFAULT_COUNT` seeds drawn with :mod:`secrets` from
  ``[2**40, 2**62)``, a range no seed set of wfbench comes near, so no public seed, test
  seed or training seed can be one of them by accident. They are stored by the server only;
  nothing it serves names them, only their commitment (below) and their index.

The list is versioned per track (version 1, 2, ... per track name) and tied to the track's
hash: a change of the track's definition needs a new list, and a test-phase submission
records the version it ran on. Its commitment, ``sha256:<hex>`` of the canonical JSON
(sorted keys, no spaces) of ``{track, track_hash, version, seeds, salt}``, is published
from the start; publishing the seeds and the salt later lets anyone check that the board
ran on the list it committed to (:func:`verify`). The salt (128 random bits) keeps the
commitment from being searched seed by seed. The seeds are JSON integers below 2**62:
a verifier must read them as exact integers (Python's ``json`` does; JavaScript's
``Number`` would not).

A policy never sees a seed: the sandbox hands it opaque per-episode keys derived from a
board secret and :func:`key_context` (:mod:`wfbench.harness.isolation.sandbox`).

Ranking a phase with :mod:`wfbench.leaderboard.report` needs a track whose ``test_seeds``
are what the rows carry as ``seed`` (:func:`board_track`): the public seeds on the dev
board, and on the test board the seed *indices* 0..n-1, never the hidden seeds, because
the reports print a track's first and last test seed in their caption.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import secrets
from dataclasses import dataclass

from wfbench.leaderboard.tracks import SuiteTrack, Track

PHASES = ("dev", "test")
DEFAULT_COUNT = 50
SEED_LOW, SEED_HIGH = 2**40, 2**62  # hidden seeds are drawn from [SEED_LOW, SEED_HIGH)
SALT_BYTES = 16


@dataclass(frozen=True)
class HiddenSeeds:
    """One version of a track's hidden test seeds, as stored (the seeds never leave the server)."""

    track: str
    track_hash: str
    version: int
    seeds: tuple[int, ...]
    salt: str  # hex
    commitment: str  # "sha256:<hex>" (:func:`commitment`)
    created: float  # epoch seconds


@dataclass(frozen=True)
class Commitment:
    """What the board publishes of a hidden seed list: everything but the seeds and the salt."""

    track: str
    track_hash: str
    version: int
    count: int
    commitment: str  # "sha256:<hex>"


def check_phase(phase: str) -> str:
    """``phase`` if it is one of :data:`PHASES`, else ValueError with a one-line message."""
    if phase not in PHASES:
        raise ValueError(f"phase {phase!r} is not allowed; allowed: {', '.join(PHASES)}")
    return phase


def draw_seeds(n: int = DEFAULT_COUNT) -> tuple[int, ...]:
    """``n`` distinct seeds from the operating system's random source, in ``[SEED_LOW, SEED_HIGH)``."""
    if not 1 <= n <= 10_000:
        raise ValueError(f"hidden seed count {n} is not allowed; allowed: 1..10000")
    out: list[int] = []
    while len(out) < n:
        s = SEED_LOW + secrets.randbelow(SEED_HIGH - SEED_LOW)
        if s not in out:
            out.append(s)
    return tuple(out)


def new_salt() -> str:
    return secrets.token_hex(SALT_BYTES)


def commitment(track: str, track_hash: str, version: int, seeds: tuple[int, ...] | list[int], salt: str) -> str:
    """``sha256:<hex>`` of the canonical JSON of ``{track, track_hash, version, seeds, salt}``."""
    text = json.dumps({"track": track, "track_hash": track_hash, "version": int(version),
                       "seeds": [int(s) for s in seeds], "salt": salt}, sort_keys=True, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def verify(published: Commitment | HiddenSeeds, seeds: tuple[int, ...] | list[int], salt: str) -> bool:
    """Whether revealed ``seeds`` and ``salt`` are those the published commitment was made of."""
    return commitment(published.track, published.track_hash, published.version, seeds, salt) == published.commitment


def make(track: Track | SuiteTrack, version: int, n: int = DEFAULT_COUNT, created: float = 0.0) -> HiddenSeeds:
    """A new hidden seed list for ``track`` with its salt and commitment."""
    seeds, salt = draw_seeds(n), new_salt()
    return HiddenSeeds(track.name, track.hash, version, seeds, salt,
                       commitment(track.name, track.hash, version, seeds, salt), created)


def public(h: HiddenSeeds) -> Commitment:
    return Commitment(h.track, h.track_hash, h.version, len(h.seeds), h.commitment)


def key_context(track: str, phase: str) -> str:
    """The context of the opaque per-episode keys of a phase of a track (with the board's secret, per seed)."""
    return f"wfbench-hosted/{track}/{check_phase(phase)}"


def phase_seeds(track: Track | SuiteTrack, phase: str, hidden: HiddenSeeds | None = None) -> tuple[int, ...]:
    """The seeds a phase runs: the public seeds (``dev``), or the hidden list (``test``, which needs ``hidden``)."""
    if check_phase(phase) == "dev":
        return tuple(track.public_seeds)
    if hidden is None:
        raise ValueError(f"the test phase of track {track.name} needs its hidden seeds")
    return hidden.seeds


def units(track: Track | SuiteTrack, seeds: tuple[int, ...]) -> list[tuple[str, int, int]]:
    """What a complete submission has a row for: (scenario, seed index, seed), scenarios in the track's order."""
    return [(scenario, i, s) for scenario in track.configs() for i, s in enumerate(seeds)]


def board_track(track: Track | SuiteTrack, phase: str, count: int = 0,
                note: str = "") -> Track | SuiteTrack:
    """The track to rank a phase's rows with: its ``test_seeds`` are what the rows carry as ``seed``.

    ``dev``: the public seeds. ``test``: the indices ``0..count-1`` of the hidden seeds
    (``count``: how many there are), and ``note`` (e.g. the commitment) added to the description.
    """
    seeds = tuple(track.public_seeds) if check_phase(phase) == "dev" else tuple(range(count))
    description = track.description + (f"; {note}" if note else "")
    if isinstance(track, SuiteTrack):
        return dataclasses.replace(track, suite=dataclasses.replace(track.suite, test_seeds=seeds),
                                   description=description)
    return dataclasses.replace(track, test_seeds=seeds, description=description)
