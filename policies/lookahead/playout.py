"""Search with the network, its futures played to the episode's end: no critic to be wrong (issue #52).

:class:`PlayoutSearch` is :class:`~wfbench.policies.lookahead.search.NetworkSearch` with each
greedy future played out to the last step of the episode and scored on the NSW it sums, so no
value estimate ends it. The truncated search's error held out is its critic's judgement of one
more person on a world it was not trained on (docs/policies.md, "A critic fitted for the
futures"): common random numbers make that judgement precise across the futures, not correct.
A played-out future needs no judgement; it costs the rest of the episode's forward passes
instead of ``H``.

On a world as large as ``city`` (:func:`~wfbench.policies.lookahead.rollout.plays_sparse`,
read from the public slot counts) a played-out future of the 1,000-person network costs hours an
episode, so there it plays the truncated search's :data:`LARGE` preset (that preset's knobs, its
value map, a deliberation every R steps only), bit for bit what that preset plays there.
docs/policies.md, "search-scalefree-general-playout".
"""

from __future__ import annotations

from typing import Any

from wfbench.policies.lookahead import search
from wfbench.policies.lookahead.search import NetworkSearch, knob, value_map

from wfbench.core.config import ScenarioConfig

# budget presets: (K, R, top, z), named by the CPU time per env-step they aim at on paper-64 (one core, whole
# episodes); chosen on the public seeds 1000-1009 of paper-64, nonstationary and table2-g256-f25-s5 (docs/policies.md,
# "search-scalefree-general-playout")
BUDGETS: dict[str, tuple[int, int, int, float]] = {
    "100ms": (4, 20, 3, 1.0),
}
KNOBS = ("K", "R", "top", "z")  # search.KNOBS less H: a future ends at the episode's end
LARGE = "10ms"  # the truncated search's preset played on a world as large as city


def budget(name: str) -> tuple[int, int, int, float]:
    """The (K, R, top, z) of a budget preset; ValueError of one line naming the presets otherwise."""
    if name not in BUDGETS:
        raise ValueError(f"playout search budget {name!r} is not allowed; allowed: {', '.join(BUDGETS)}")
    return BUDGETS[name]


class PlayoutSearch(NetworkSearch):
    """Search with the network ``base`` on K greedy futures played to the episode's end (module docstring).

    Args:
        base: a network deciding all three decisions (``policies.get("scalefree-general")``).
        K, R, top, z: the knobs (:data:`wfbench.policies.lookahead.search.KNOBS`); None takes the
            ``budget`` preset's.
        budget: a preset of :data:`BUDGETS`.
        large: the truncated search's preset (:data:`wfbench.policies.lookahead.search.BUDGETS`)
            played on a world as large as ``city``.
        scenario, seed, name: as :class:`NetworkSearch`.

    Where it deliberates, its candidates, the greedy futures with common random numbers and the
    noise test are :class:`NetworkSearch`'s; ``decide`` is ``"auto"``.
    """

    def __init__(self, base: Any, K: int | None = None, R: int | None = None, top: int | None = None,
                 z: float | None = None, budget: str = "100ms", large: str = LARGE,
                 scenario: ScenarioConfig | None = None, seed: int = 0, name: str | None = None):
        preset = globals()["budget"](budget)
        given = dict(zip(KNOBS, (K, R, top, z), strict=True))
        k, r, t, zz = (knob(n, preset[i] if v is None else v) for i, (n, v) in enumerate(given.items()))
        self.large = search.budget(large)
        self.large_name = large
        # H = 1 stands for "the episode's end" until the first observation says how far that is
        super().__init__(base, K=k, H=1, R=r, top=t, z=zz, value=(), scenario=scenario, seed=seed,
                         name=name or f"search-{getattr(base, 'name', 'network')}-playout", decide="auto")
        self.small = (k, r, t, zz)

    def settings(self) -> dict[str, Any]:
        K, R, top, z = self.small
        return {"K": K, "H": "end", "R": R, "top": top, "z": z, "futures": self.futures, "large": self.large_name}

    def _start(self, obs) -> None:
        super()._start(obs)  # sets self.period from the world's size, and self.horizon
        if self.period:  # a world as large as city: the truncated search's preset, its value map
            self.K, self.H, self.R, self.top, self.z = self.large
            world = self.config.name if self.config is not None else ""
            self.value = value_map(getattr(self.base, "name", ""), world)
        else:  # to the end, scored on the NSW summed: no critic
            self.K, self.R, self.top, self.z = self.small
            self.H, self.value = self.horizon, ()


def make(base: Any, budget_name: str = "100ms", name: str | None = None, **knobs: Any) -> PlayoutSearch:
    """A :class:`PlayoutSearch` of ``base`` at a budget preset, knobs overriding it."""
    return PlayoutSearch(base, budget=budget_name, name=name, **knobs)


__all__ = ["BUDGETS", "KNOBS", "LARGE", "PlayoutSearch", "budget", "make"]
