"""Observation and action spaces shared by the PettingZoo and Gymnasium environments.

Two observation versions (``obs_version=``, :data:`wfbench.core.observation_v2.OBS_VERSIONS`):
1, the paper's (coordinates in grid cells; ``wfbench/Workforce-v0``), and 2 (coordinates
in travel-time steps, plus ``context`` and ``units``; ``wfbench/Workforce-v1``), derived
from the simulator's observation by :func:`wfbench.core.observation_v2.observe_v2`. Neither
space has the simulator's ``world`` key: version 1 stays as it was, and version 2 holds
the same parameters scale-free in ``context`` and the units apart in ``units``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from wfbench.core.actions import ActionError
from wfbench.core.config import ScenarioConfig
from wfbench.core.observation_v2 import (
    CONTEXT_FEATURES,
    OBS_VERSIONS,
    UNIT_FEATURES,
    V2_KEYS,
    C,
    W,
    WorldKey,
    observe_v2,
)
from wfbench.core.observe import FACILITY_FEATURES, GLOBAL_FEATURES, PERSONNEL_FEATURES
from wfbench.core.state import N_WORKFORCE_ACTIONS

# Positioning weights are quantized to this many levels in MultiDiscrete action spaces.
POSITIONING_LEVELS = 11
SHARED_KEYS = (
    "facilities", "personnel", "facility_mask", "personnel_mask", "personnel_status", "under_notice",
    "dispatchable", "requesting", "globals",
)


def check_obs_version(value: Any) -> int:
    """``value`` as an int if it is one of :data:`OBS_VERSIONS`, else a one-line ValueError naming them.

    Stricter than :func:`check_option`: ``True`` and ``2.0`` compare equal to 1 and 2 but are refused.
    """
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool) and int(value) in OBS_VERSIONS
    if not ok:
        raise ValueError(f"obs_version={value!r} is not allowed; allowed: {', '.join(map(str, OBS_VERSIONS))}")
    return int(value)


def shared_keys(obs_version: int) -> tuple[str, ...]:
    """The keys of the shared observation (no action masks) of an observation version."""
    return SHARED_KEYS if obs_version == 1 else (*SHARED_KEYS, *V2_KEYS)


def versioned(obs: dict[str, np.ndarray], obs_version: int) -> dict[str, np.ndarray]:
    """The simulator's batched observation in ``obs_version``: itself (1) or :func:`observe_v2` of it (2)."""
    return obs if obs_version == 1 else observe_v2(obs)


def _binary(*shape: int) -> spaces.Box:
    return spaces.Box(0, 1, shape=shape, dtype=np.int8)


def shared_spaces(c: ScenarioConfig, obs_version: int = 1) -> dict[str, spaces.Space]:
    """The shared observation's spaces; version 2 has coordinates in travel time and ``context``, ``units``."""
    M, N = c.max_facilities, c.max_personnel
    xmax, ymax = c.grid_width - 1, c.grid_height - 1
    if obs_version == 2:  # the float64 quotient rounded once to float32, as observe_v2 rounds a coordinate
        xmax, ymax = xmax / c.speed, ymax / c.speed
    f_lo = np.array([0, 0, 0, 0, 0, -1, 0], dtype=np.float32)
    f_hi = np.array([xmax, ymax, 1, 1, 1, N - 1, 1], dtype=np.float32)
    p_lo = np.array([0, 0, 0, 0, 0, 0, -1, 0, 0], dtype=np.float32)
    p_hi = np.array([xmax, ymax, xmax, ymax, 2, 1, M - 1, 1, 1], dtype=np.float32)
    assert len(f_lo) == len(FACILITY_FEATURES) and len(p_lo) == len(PERSONNEL_FEATURES)
    out: dict[str, spaces.Space] = {
        "facilities": spaces.Box(np.tile(f_lo, (M, 1)), np.tile(f_hi, (M, 1)), dtype=np.float32),
        "personnel": spaces.Box(np.tile(p_lo, (N, 1)), np.tile(p_hi, (N, 1)), dtype=np.float32),
        "facility_mask": _binary(M),
        "personnel_mask": _binary(N),
        "personnel_status": spaces.Box(0, 5, shape=(N,), dtype=np.int8),
        "under_notice": _binary(N),
        "dispatchable": _binary(N),
        "requesting": _binary(M),
        "globals": spaces.Box(0.0, 1.0, shape=(len(GLOBAL_FEATURES),), dtype=np.float32),
    }
    if obs_version == 2:
        low, high = context_bounds(c)
        units = np.array([c.speed, c.grid_width, c.grid_height], dtype=np.float32)
        assert len(units) == len(UNIT_FEATURES)
        out["context"] = spaces.Box(low, high, dtype=np.float32)
        out["units"] = spaces.Box(np.zeros_like(units), units, dtype=np.float32)
    return out


def context_bounds(c: ScenarioConfig) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) float32 of :data:`~wfbench.core.observation_v2.CONTEXT_FEATURES` in the world ``c``.

    Every column is >= 0, so low is 0 (below 0 only for a rate whose schedule goes
    negative). high is the greatest value the column takes in this world: for the
    world's parameters, their value and, for the rates, the greatest multiplier of their
    schedule over the episode, computed by :func:`observe_v2` itself so that the bits
    agree; the step and the time left, the horizon; the counts, the slots; the ratios (a
    count of 0 divides as 1), what the counts allow (``facilities_per_person`` and
    ``open_per_free`` at most M, ``load_per_person`` at most 1 + M, busy people being
    employed ones). A parameter that is 0 gets high 1: Gymnasium's checker refuses a Box
    whose low equals its high, so a constant never gets [v, v].
    """
    M, N, H = c.max_facilities, c.max_personnel, c.horizon
    key = WorldKey(c, 2)
    world = key.buffer.copy()
    for name, m in (("request_multiplier", key.request), ("churn_multiplier", key.churn)):
        world[:, W[name]] = (m.min(), m.max())
    blank = {"facilities": np.zeros((2, 1, len(FACILITY_FEATURES)), np.float32),
             "personnel": np.zeros((2, 1, len(PERSONNEL_FEATURES)), np.float32), "t": np.zeros(2, np.int64),
             "world": world, **{k: np.zeros((2, 1), np.int8) for k in
                                ("facility_mask", "personnel_mask", "dispatchable", "requesting")}}
    least, high = observe_v2(blank)["context"]
    low = np.minimum(least, 0.0)
    for name, hi in (("t", H), ("time_left", H), ("active_facilities", M), ("employed", N), ("free", N),
                     ("busy", N), ("open_requests", M), ("facilities_per_person", M), ("open_per_free", M),
                     ("load_per_person", M + 1)):
        high[C[name]] = hi
    high = np.where(high > low, high, low + 1.0).astype(np.float32)
    assert len(low) == len(CONTEXT_FEATURES)
    return low, high


def dispatch_action_space(c: ScenarioConfig) -> spaces.MultiDiscrete:
    """Entry f: the person sent to facility slot f, or N for none."""
    return spaces.MultiDiscrete(np.full(c.max_facilities, c.max_personnel + 1, dtype=np.int64))


def workforce_action_space() -> spaces.Discrete:
    """0 no-op, 1..3 hire a novice / mid / expert, 4..6 let go a novice / mid / expert."""
    return spaces.Discrete(N_WORKFORCE_ACTIONS)


def positioning_action_space(c: ScenarioConfig) -> spaces.Box:
    """Row 0: weights of the facilities for placing a hire; row 1: for choosing whom to let go."""
    return spaces.Box(0.0, 1.0, shape=(2, c.max_facilities), dtype=np.float32)


def flat_positioning_action_space(c: ScenarioConfig) -> spaces.Box:
    """The ``positioning="flat"`` action: the (2, M) weights as one (2M,) ``Box``, row 0 then row 1.

    Gymnasium's flattening of :func:`positioning_action_space`; :func:`unflatten_positioning` reads an action of it.
    """
    return spaces.flatten_space(positioning_action_space(c))


def unflatten_positioning(action: Any, M: int) -> np.ndarray:
    """A ``positioning="flat"`` action as the (2, M) weights: the same numbers, in their own dtype, reshaped.

    Not :func:`gymnasium.spaces.unflatten`, which casts to the space's float32: a float64 action
    keeps its bits, so a flat and a 2-D action of the same numbers give the same step.
    """
    a = np.asarray(action)
    if a.shape != (2 * M,):
        raise ActionError(f"action of agent 'positioning' has shape {a.shape}; allowed: ({2 * M},), "
                          f"the flat positioning Box (positioning='flat')")
    return a.reshape(2, M)


def single(obs: dict[str, np.ndarray], keys, b: int = 0) -> dict[str, np.ndarray]:
    """Environment b of a batched observation, copied, for the given keys.

    A batch of one (the environments) copies each whole array and returns its row: numpy
    copies a contiguous array in about half the time it takes to copy a row view.
    """
    if len(obs["facilities"]) == 1 and b == 0:
        return {k: obs[k].copy()[0] for k in keys}
    return {k: obs[k][b].copy() for k in keys}


OBSERVATIONS = ("dict", "box")  # the ``observation=`` option: a Dict of Boxes, or those flattened into one Box
INFOS = ("flat", "nested")  # the ``info=`` option: numbers only, or the tallies in nested dicts
POSITIONINGS = ("2d", "flat")  # the ``positioning=`` option: the (2, M) Box, or its (2M,) flattening


def check_option(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    """``value`` if it is one of ``allowed``, else a one-line ValueError naming them."""
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not allowed; allowed: {', '.join(map(repr, allowed))}")
    return value


def observation_space(dict_space: spaces.Dict, observation: str) -> spaces.Space:
    """The space of the ``observation=`` option: the Dict itself, or Gymnasium's flattening of it (float32)."""
    return dict_space if observation == "dict" else spaces.flatten_space(dict_space)


def flatten_batch(dict_space: spaces.Dict, obs: dict[str, np.ndarray]) -> np.ndarray:
    """(B, n) float32: each row is ``gymnasium.spaces.flatten(dict_space, row)``, for a whole batch at once."""
    B = len(next(iter(obs.values())))
    return np.concatenate([obs[k].reshape(B, -1) for k in dict_space.spaces], axis=1, dtype=np.float32)


def joint_nvec(c: ScenarioConfig) -> np.ndarray:
    """The joint MultiDiscrete of Workforce-v0: M dispatch entries (0..N), the workforce action, 2M levels."""
    M, N = c.max_facilities, c.max_personnel
    return np.concatenate([np.full(M, N + 1), [N_WORKFORCE_ACTIONS], np.full(2 * M, POSITIONING_LEVELS)]).astype(
        np.int64)


def split_joint(a: np.ndarray, M: int) -> dict[str, np.ndarray]:
    """The three decisions of joint actions (..., 1 + 3M): positioning levels become weights level / 10."""
    lead = a.shape[:-1]
    pos = a[..., M + 1 :]
    bad = (pos < 0) | (pos >= POSITIONING_LEVELS)
    if bad.any():
        i = tuple(int(x) for x in np.argwhere(bad)[0])
        raise ActionError(f"positioning action: {pos[i]} at index {i} is out of range; "
                          f"allowed: integers 0..{POSITIONING_LEVELS - 1}")
    return {"dispatch": a[..., :M], "workforce": a[..., M],
            "positioning": (pos.astype(np.float64) / (POSITIONING_LEVELS - 1)).reshape(*lead, 2, M)}

