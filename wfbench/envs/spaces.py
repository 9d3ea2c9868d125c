"""Observation and action spaces shared by the PettingZoo and Gymnasium environments."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from wfbench.core.actions import ActionError
from wfbench.core.config import ScenarioConfig
from wfbench.core.observe import FACILITY_FEATURES, GLOBAL_FEATURES, PERSONNEL_FEATURES
from wfbench.core.state import N_WORKFORCE_ACTIONS

# Positioning weights are quantized to this many levels in MultiDiscrete action spaces.
POSITIONING_LEVELS = 11
SHARED_KEYS = (
    "facilities", "personnel", "facility_mask", "personnel_mask", "personnel_status", "under_notice",
    "dispatchable", "requesting", "globals",
)
OBS_KEYS = (*SHARED_KEYS, "dispatch_mask", "workforce_mask")


def _binary(*shape: int) -> spaces.Box:
    return spaces.Box(0, 1, shape=shape, dtype=np.int8)


def shared_spaces(c: ScenarioConfig) -> dict[str, spaces.Space]:
    M, N = c.max_facilities, c.max_personnel
    xmax, ymax = c.grid_width - 1, c.grid_height - 1
    f_lo = np.array([0, 0, 0, 0, 0, -1, 0], dtype=np.float32)
    f_hi = np.array([xmax, ymax, 1, 1, 1, N - 1, 1], dtype=np.float32)
    p_lo = np.array([0, 0, 0, 0, 0, 0, -1, 0, 0], dtype=np.float32)
    p_hi = np.array([xmax, ymax, xmax, ymax, 2, 1, M - 1, 1, 1], dtype=np.float32)
    assert len(f_lo) == len(FACILITY_FEATURES) and len(p_lo) == len(PERSONNEL_FEATURES)
    return {
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


def dispatch_action_space(c: ScenarioConfig) -> spaces.MultiDiscrete:
    """Entry f: the person sent to facility slot f, or N for none."""
    return spaces.MultiDiscrete(np.full(c.max_facilities, c.max_personnel + 1, dtype=np.int64))


def workforce_action_space() -> spaces.Discrete:
    """0 no-op, 1..3 hire a novice / mid / expert, 4..6 let go a novice / mid / expert."""
    return spaces.Discrete(N_WORKFORCE_ACTIONS)


def positioning_action_space(c: ScenarioConfig) -> spaces.Box:
    """Row 0: weights of the facilities for placing a hire; row 1: for choosing whom to let go."""
    return spaces.Box(0.0, 1.0, shape=(2, c.max_facilities), dtype=np.float32)


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

