"""The two phases of a hosted track: development on the public seeds, test on hidden seeds held by the server.

``dev`` runs the track's public seeds and shows the log and per-seed rows. ``test`` runs
:data:`DEFAULT_COUNT` seeds drawn with :mod:`secrets` from ``[2**40, 2**62)``, far from every seed
set of wfbench, stored by the server only. Each list is versioned per track and tied to its hash;
its commitment (sha256 of canonical JSON with a salt) is published from the start, and
:func:`verify` checks a revealed list against it. Policies see opaque keys
(:func:`key_context`), never seeds; :func:`board_track` gives the reports the seed indices.
``docs/leaderboard.md``, "Phases, seeds and keys".
"""

from __future__ import annotations

import hashlib
import json
import secrets
from dataclasses import dataclass

from wfbench.leaderboard.tracks import Track

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


def make(track: Track, version: int, n: int = DEFAULT_COUNT, created: float = 0.0) -> HiddenSeeds:
    """A new hidden seed list for ``track`` with its salt and commitment."""
    seeds, salt = draw_seeds(n), new_salt()
    return HiddenSeeds(track.name, track.hash, version, seeds, salt,
                       commitment(track.name, track.hash, version, seeds, salt), created)


def public(h: HiddenSeeds) -> Commitment:
    return Commitment(h.track, h.track_hash, h.version, len(h.seeds), h.commitment)


def key_context(track: str, phase: str) -> str:
    """The context of the opaque per-episode keys of a phase of a track (with the board's secret, per seed)."""
    return f"wfbench-hosted/{track}/{check_phase(phase)}"


def phase_seeds(track: Track, phase: str, hidden: HiddenSeeds | None = None) -> tuple[int, ...]:
    """The seeds a phase runs: the public seeds (``dev``), or the hidden list (``test``, which needs ``hidden``)."""
    if check_phase(phase) == "dev":
        return tuple(track.public_seeds)
    if hidden is None:
        raise ValueError(f"the test phase of track {track.name} needs its hidden seeds")
    return hidden.seeds


def units(track: Track, seeds: tuple[int, ...]) -> list[tuple[str, int, int]]:
    """What a complete submission has a row for: (scenario, seed index, seed), scenarios in the track's order."""
    return [(scenario, i, s) for scenario in track.configs() for i, s in enumerate(seeds)]


def board_track(track: Track, phase: str, count: int = 0,
                note: str = "") -> Track:
    """The track to rank a phase's rows with: its ``test_seeds`` are what the rows carry as ``seed``.

    ``dev``: the public seeds. ``test``: the indices ``0..count-1`` of the hidden seeds
    (``count``: how many there are), and ``note`` (e.g. the commitment) added to the description.
    """
    seeds = tuple(track.public_seeds) if check_phase(phase) == "dev" else tuple(range(count))
    description = track.description + (f"; {note}" if note else "")
    return track.with_seeds(seeds, description)
