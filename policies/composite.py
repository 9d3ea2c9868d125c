"""The composite: one policy per decision, which is how the paper's Table 3 rows are built.

``Composite(dispatch=..., workforce=..., positioning=...)`` takes for each decision a
policy object or the name of a built-in decision policy (:data:`wfbench.policies.decisions.DECISIONS`).
A composite made only of built-in kernels can run whole episodes compiled
(:meth:`Composite.compiled_plan`, :func:`wfbench.policies.episode.play_episodes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from wfbench.policies import kernels as K
from wfbench.policies.builtin import BuiltinDecision
from wfbench.policies.decisions import DECISIONS
from wfbench.policies.protocol import decision_key, seeds_array
from wfbench.policies.tunable import Param

from wfbench.core.actions import AGENTS


def _decision_policy(decision: str, spec: Any) -> Any:
    if isinstance(spec, str):
        table = DECISIONS[decision]
        if spec not in table:
            raise ValueError(f"unknown {decision} policy {spec!r}; available: {', '.join(table)}")
        return table[spec]()
    if not hasattr(spec, "act") or decision not in getattr(spec, "decisions", AGENTS):
        raise ValueError(f"{spec!r} cannot make the {decision} decision")
    return spec


class Composite:
    """One policy per decision: ``Composite(dispatch=..., workforce=..., positioning=...)``.

    Each argument is a policy object or the name of a built-in decision policy
    (:data:`wfbench.policies.decisions.DECISIONS`).
    """

    def __init__(self, dispatch: Any, workforce: Any, positioning: Any, name: str | None = None):
        self.parts = {
            "dispatch": _decision_policy("dispatch", dispatch),
            "workforce": _decision_policy("workforce", workforce),
            "positioning": _decision_policy("positioning", positioning),
        }
        self.decisions = AGENTS
        self.name = name or "+".join(getattr(p, "name", type(p).__name__) for p in self.parts.values())
        self._unique = list({id(p): p for p in self.parts.values()}.values())
        # hindsight oracles (wfbench.policies.oracle) share one planner and model the built-in parts exactly
        joiners = [p for p in self._unique if getattr(p, "reads_trace", False) and hasattr(p, "join")]
        if joiners:
            joiners[0].join(self.parts)
        self._recorders = [p for p in self._unique if hasattr(p, "record")]

    @property
    def reads_trace(self) -> bool:
        """True when a part reads the episode's future (a hindsight oracle): not deployable."""
        return any(getattr(p, "reads_trace", False) for p in self._unique)

    def attach(self, config: Any) -> None:
        """Hand the scenario to the parts that read the trace (the runner calls this before ``reset``)."""
        for p in self._unique:
            if getattr(p, "reads_trace", False) and hasattr(p, "attach"):
                p.attach(config)

    def __repr__(self) -> str:
        return f"Composite({self.name!r})"

    def reset(self, seeds: int | Sequence[int]) -> None:
        done: set[int] = set()
        for p in self.parts.values():
            if id(p) not in done:
                p.reset(seeds)
                done.add(id(p))

    def act(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        cache: dict[int, dict[str, np.ndarray]] = {}
        for decision, p in self.parts.items():
            if id(p) not in cache:
                cache[id(p)] = p.act(obs)
            out[decision] = cache[id(p)][decision]
        for p in self._recorders:  # parts that track the episode (the oracles' shadow) learn the joint action
            p.record(out)
        return out

    @property
    def tunable(self) -> dict[str, Param]:
        """Its parts' tunable hyper-parameters as ``decision.field`` -> range (``workforce.high``).

        Only built-in kernel parts declare any (:data:`wfbench.policies.rules.RULES`); ``wfbench tune``
        searches these.
        """
        out: dict[str, Param] = {}
        for decision, part in self.parts.items():
            if isinstance(part, BuiltinDecision):
                out.update({f"{decision}.{f}": p for f, p in part.tunable.items()})
        return out

    def params(self) -> dict[str, float | int]:
        """The current value of each tunable hyper-parameter, by ``decision.field``."""
        out: dict[str, float | int] = {}
        for decision, part in self.parts.items():
            if isinstance(part, BuiltinDecision):
                for f, v in part.params().items():
                    out[f"{decision}.{f}"] = int(v) if part.tunable[f].type == "int" else v
        return out

    def with_params(self, params: dict[str, float], name: str | None = None) -> Composite:
        """A new composite with the given tunable hyper-parameters (``decision.field`` -> value) changed.

        Raises:
            ValueError: a name that is not in :attr:`tunable` or a value outside its
                range, naming what is allowed.
        """
        allowed = self.tunable
        by_part: dict[str, dict[str, float]] = {d: {} for d in AGENTS}
        for key, value in params.items():
            if key not in allowed:
                raise ValueError(f"{self.name} has no tunable parameter {key!r}; allowed: "
                                 f"{', '.join(allowed) or 'none (no part is a built-in kernel with parameters)'}")
            by_part[key.partition(".")[0]][key.partition(".")[2]] = allowed[key].check(value, key)
        parts = {d: (p.with_params(**by_part[d]) if by_part[d] else p) for d, p in self.parts.items()}
        return Composite(**parts, name=name or self.name)

    @property
    def compiled(self) -> bool:
        """True when every part is a built-in kernel, so a whole episode can run compiled."""
        return all(isinstance(p, BuiltinDecision) for p in self.parts.values())

    def compiled_plan(self, seeds: Sequence[int], M: int, N: int) -> tuple[np.ndarray, np.ndarray, K.PolicyState]:
        """Codes, hyper-parameters and fresh state for :func:`wfbench.policies.episode.play_episodes`."""
        if not self.compiled:
            raise ValueError(f"{self!r} has parts that are not built-in kernels")
        seeds = seeds_array(seeds)
        B = len(seeds)
        codes = np.array([self.parts[d].code for d in AGENTS], dtype=np.int64)
        hp = np.stack([self.parts[d].hp for d in AGENTS])
        state = K.allocate_state(B, M, N)
        for d, decision in enumerate(AGENTS):
            part = self.parts[decision]
            for b, s in enumerate(seeds):
                state.keys[b, d] = decision_key(s, part.seed, decision)
        return codes, hp, state
