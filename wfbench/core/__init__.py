"""The simulator core: everything a simulation needs and nothing that decides or reports.

Configuration and presets, seed sets, rate schedules, counter-based random numbers, the
trace, the state arrays, the KPI table and rewards, the model rules (``dynamics``), hire
placement, the observation, the batched :class:`~wfbench.core.simulator.Simulator`, the
numba cache (``jit``), two analyses of the core: ``fork`` (copy the true state and fork a
simulator) and ``bound`` (the proven upper bound on the score), and ``belief``, the simulator
a deployable lookahead builds from what it has observed (its own second world generator
beside ``trace``: the unobserved parts drawn from the public model under the policy's keys). It imports nothing of
wfbench above it and no solver (``docs/design.md``, layers). The names users need are on
the package ``wfbench`` itself (``wfbench.ScenarioConfig``, ``wfbench.Simulator``,
``wfbench.trace``).
"""
