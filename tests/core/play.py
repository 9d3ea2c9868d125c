"""Random play shared by the fork tests: actions that exercise every kind of event."""

import numpy as np


def random_actions(B: int, M: int, N: int, obs: dict, rng: np.random.Generator, hire_rate: float) -> dict:
    """Dispatch most open requests, hire or let go in a ``hire_rate`` share of the environments.

    A random level 1-6 is a hire or a let-go, some of them impossible, which the simulator
    counts; the positioning maps are uniform noise.
    """
    dispatch = np.full((B, M), N, dtype=np.int64)
    for b in range(B):
        free = list(np.flatnonzero(obs["dispatchable"][b]))
        for f in np.flatnonzero(obs["requesting"][b]):
            if free and rng.random() < 0.8:
                dispatch[b, f] = free.pop(int(rng.integers(len(free))))
    workforce = np.where(rng.random(B) < hire_rate, rng.integers(1, 7, size=B), 0).astype(np.int64)
    return {"dispatch": dispatch, "workforce": workforce, "positioning": rng.random((B, 2, M))}
