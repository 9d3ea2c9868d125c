"""wfbench: a benchmark suite for service workforce optimization."""

__version__ = "0.1.0"

from wfbench.config import ScenarioConfig
from wfbench.envs import env, parallel_env, register_envs
from wfbench.evaluate import evaluate
from wfbench.schedule import RateSchedule
from wfbench.simulator import ActionError, Simulator
from wfbench.trace import trace

register_envs()

__all__ = [
    "ActionError", "RateSchedule", "ScenarioConfig", "Simulator", "env", "evaluate", "parallel_env", "trace",
    "__version__",
]
