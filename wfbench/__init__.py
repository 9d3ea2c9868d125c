"""wfbench: a benchmark suite for service workforce optimization."""

__version__ = "0.1.0"

from wfbench.config import ScenarioConfig
from wfbench.schedule import RateSchedule
from wfbench.simulator import ActionError, Simulator
from wfbench.trace import trace

__all__ = ["ActionError", "RateSchedule", "ScenarioConfig", "Simulator", "trace", "__version__"]
