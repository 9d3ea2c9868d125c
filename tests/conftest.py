import warnings

import pytest

from wfbench import ScenarioConfig

# SB3's checker recommends flat observations; entity features are (M, 7) and (N, 9) on purpose
# (docs/model.md). Only these known advisories are let through; any other warning in the checks fails.
KNOWN_ADVISORIES = (
    "Your observation .* has an unconventional shape",
    "Observation is not a NumPy array",
    "Observation space for each agent probably should be",
    "Action space for each agent probably should be",
    "We recommend agents to be named in the format",
)


@pytest.fixture
def strict_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for pattern in KNOWN_ADVISORIES:
            warnings.filterwarnings("ignore", message=pattern)
        yield


@pytest.fixture
def tiny():
    """3 personnel, 5 facilities on a 12x12 grid."""
    return ScenarioConfig(name="tiny", grid_width=12, grid_height=12, max_facilities=5, max_personnel=3,
                          initial_facilities=5, initial_personnel=3, horizon=60, request_interval=10.0,
                          window=10)
