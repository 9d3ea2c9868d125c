"""wfbench: a benchmark suite for service workforce optimization.

Importing ``wfbench`` loads the simulator core (``ScenarioConfig``, ``Simulator``,
``trace``) and registers the Gymnasium ids by their string entry points. The names of
the layers above the core (``scenario``, the one resolver of scenario names;
``Execution``, where episodes run; ``evaluate``, ``compare``, ``simulate``, ``env``,
``parallel_env``) are imported on first use, so importing the core never pulls in
``policies`` or the application layer (``docs/design.md``, layers).
"""

__version__ = "0.1.0"

import warnings as _warnings

import gymnasium as _gymnasium

from wfbench.core import lazy as _lazy
from wfbench.core.actions import ActionError
from wfbench.core.config import ScenarioConfig
from wfbench.core.schedule import RateSchedule
from wfbench.core.simulator import Simulator
from wfbench.core.trace import trace

# Gymnasium imports an entry point's module only when an environment is made. The vector
# entry points make ``gymnasium.make_vec(id, num_envs=B)`` one batched WorkforceVectorEnv.
# A changed observation is a new version of an id (Gymnasium's convention): Workforce-v1 is
# Workforce-v0 with observation version 2 (wfbench.core.observation_v2), its registered kwargs.
ENV_IDS = {
    "wfbench/Workforce-v0": "wfbench.envs.gym_env:WorkforceEnv",
    "wfbench/Workforce-v1": "wfbench.envs.gym_env:WorkforceEnv",
    "wfbench/Dispatch-v0": "wfbench.envs.gym_env:DispatchEnv",
}
VECTOR_ENTRY_POINTS = {
    "wfbench/Workforce-v0": "wfbench.envs.vector:workforce_vector_env",
    "wfbench/Workforce-v1": "wfbench.envs.vector:workforce_vector_env",
    "wfbench/Dispatch-v0": "wfbench.envs.vector:dispatch_vector_env",
}
ENV_KWARGS = {"wfbench/Workforce-v1": {"obs_version": 2}}
# Gymnasium calls an id "out of date" once a higher version is registered. Workforce-v0 is not: it is
# the paper's observation, which the leaderboard and every shipped network read; v1 is another view.
V0_CURRENT = r".*The environment wfbench/Workforce-v0 is out of date"
_warnings.filterwarnings("ignore", message=V0_CURRENT, category=DeprecationWarning)
for _env_id, _entry in ENV_IDS.items():
    if _env_id not in _gymnasium.registry:
        _gymnasium.register(id=_env_id, entry_point=_entry, vector_entry_point=VECTOR_ENTRY_POINTS[_env_id],
                            disable_env_checker=False, kwargs=ENV_KWARGS.get(_env_id, {}))

_LAZY = {"scenario": "wfbench.scenarios.resolve:resolve_scenario", "Execution": "wfbench.harness.backends",
         "evaluate": "wfbench.harness.evaluation",
         "evaluate_suite": "wfbench.harness.suite",
         "compare": "wfbench.harness.compare", "simulate": "wfbench.harness.simulate", "env": "wfbench.envs",
         "parallel_env": "wfbench.envs"}


__getattr__, __dir__ = _lazy.names(__name__, _LAZY)  # the application-layer names, imported on first use


__all__ = [
    "ActionError", "ENV_IDS", "Execution", "RateSchedule", "ScenarioConfig", "Simulator", "compare", "env", "evaluate",
    "evaluate_suite", "parallel_env", "scenario", "simulate", "trace", "__version__",
]
