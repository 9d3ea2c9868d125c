"""``wfbench serve seed``: the built-in baselines on a hosted board, as submissions of the admin account 'wfbench'.

The reports compare every entry with ``heuristic``, so :func:`seed` enters the built-ins of
``LINEUPS["leaderboard"]`` as ordinary submissions (:func:`builtin_package`: an entry wrapping the
registry name), evaluated by the workers in the sandbox like any upload; a stochastic built-in
draws from the opaque keys, so its rows differ from the local board's, and one that reads the
trace is left out. Seeding again adds nothing (the same bytes), another account's upload of
them is its own entry, and the quotas do not apply. ``docs/leaderboard.md``, "Starting one".
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import sqlalchemy as sa
from wfbench.leaderboard.board import hidden
from wfbench.leaderboard.board.db import BUILTIN_ACCOUNT, Account, Board, BoardError, accounts
from wfbench.policies import registry

from wfbench.harness.isolation.package import pack

ACCOUNT = BUILTIN_ACCOUNT  # the admin account the built-ins are submitted under (its token is thrown away)
ENTRY = "wfbench_builtin:policy"
MODULE = '''"""The built-in policy {name!r} of the wfbench the worker runs, entered by `wfbench serve seed`."""

from wfbench.policies import get

NAME = {name!r}


def policy():
    return get(NAME)
'''
PHASES = {"dev": ("dev",), "test": ("test",), "both": ("dev", "test")}


@dataclass(frozen=True)
class Seeded:
    """What seeding did for one built-in on one track and phase: its submission (new or not), or why it was left out."""

    name: str
    track: str
    phase: str
    submission_id: int | None = None
    state: str = ""
    created: bool = False
    left_out: str = ""  # why the built-in was not entered ("" when it was)

    def line(self) -> str:
        where = f"{self.name} on {self.track} ({self.phase})"
        if self.left_out:
            return f"{where}: left out: {self.left_out}"
        if self.created:
            return f"{where}: submission {self.submission_id} queued"
        return f"{where}: already there, submission {self.submission_id} ({self.state})"


def builtin_package(name: str) -> bytes:
    """The package of the built-in ``name``: one module whose entry returns ``get(name)``; the same bytes every time."""
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "wfbench_builtin.py").write_text(MODULE.format(name=name))
        return pack(ENTRY, tmp)


def seed_account(board: Board) -> Account:
    """The admin account ``wfbench``, made if missing (its token is not kept: nobody uploads as it)."""
    for _ in range(2):
        with board.engine.begin() as conn:
            r = conn.execute(sa.select(accounts).where(accounts.c.name == ACCOUNT)).mappings().first()
        if r is not None:
            if not r["admin"]:
                raise BoardError(f"account {ACCOUNT!r} exists and is not an admin account; the built-ins are entered "
                                 f"only under an admin account of that name (rename the other one in the database)")
            return Account(r["id"], r["name"], True, r["created"])
        try:
            board.add_account(ACCOUNT, admin=True)
        except BoardError:  # made by another seeding at the same moment: read it again
            pass
    raise BoardError(f"cannot make the admin account {ACCOUNT!r}")


def sandboxable(name: str) -> str:
    """Why the built-in ``name`` cannot run in the sandbox ("" when it can)."""
    if getattr(registry.get(name), "reads_trace", False):
        return "it reads the trace (a hindsight oracle); a sandboxed policy sees observations only"
    return ""


def seed(board: Board, tracks: Iterable[str] | None = None, phases: Sequence[str] = ("dev", "test"),
         names: Sequence[str] = registry.LINEUPS["leaderboard"]) -> list[Seeded]:
    """Enter the built-ins ``names`` on ``tracks`` (default: all the board's) in ``phases``; one record each.

    Raises:
        BoardError: an unknown track or phase, or an account ``wfbench`` that is not an admin.
    """
    for phase in phases:
        try:
            hidden.check_phase(phase)
        except ValueError as exc:
            raise BoardError(str(exc)) from None
    track_names = list(board.tracks if tracks is None else tracks)
    for t in track_names:
        board.track(t)
    account = seed_account(board)
    why = {n: sandboxable(n) for n in names}
    shas = {n: board.put_package(builtin_package(n)) for n in names if not why[n]}
    out = []
    for t in track_names:
        for phase in phases:
            for n in names:
                if why[n]:
                    out.append(Seeded(n, t, phase, left_out=why[n]))
                    continue
                sub, created = board.submit(account, t, phase, shas[n], ENTRY, n, quota=False)
                out.append(Seeded(n, t, phase, sub.id, sub.state, created))
    return out
