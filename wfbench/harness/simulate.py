"""One episode of one policy on one seed, a step at a time, optionally drawn: :func:`simulate` (``wfbench simulate``).

Where :func:`wfbench.evaluate` plays whole episodes of many seeds for their KPIs,
``simulate`` plays one episode the way one watches it: step by step, up to ``steps``,
with a frame of the world every ``every`` steps when ``render`` names a GIF to write.
The policy is loaded once through :func:`wfbench.harness.guard.load_policy`, as in an
evaluation: a built-in runs as it is (a hindsight oracle is handed the scenario first,
as :func:`wfbench.harness.runner.run_batch` does), and a user's policy (``module:attr`` or
an object) runs through its guard, so its failure is one line
(:class:`~wfbench.harness.guard.PolicyError`).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wfbench.core.config import ScenarioConfig
from wfbench.core.kpis import KPI_NAMES
from wfbench.core.simulator import Simulator
from wfbench.harness.guard import DEFAULT_ACT_TIMEOUT_S, load_policy
from wfbench.scenarios.resolve import resolve_scenario


@dataclass(frozen=True)
class Episode:
    """What :func:`simulate` played: the scenario, seed and policy, the steps, the KPIs and the GIF written."""

    scenario: ScenarioConfig
    seed: int
    policy: str  # the policy's name (its spec, or its object's name)
    steps: int  # steps played (the horizon, or fewer when ``steps`` stopped the episode)
    kpis: dict[str, float]  # the mean of each KPI (wfbench.core.kpis.KPI_NAMES) over the steps played
    frames: int  # frames in the GIF (0 without ``render``)
    gif: Path | None  # the GIF written, or None


def simulate(policy: Any = "heuristic", scenario: str | Path | ScenarioConfig = "paper-64", seed: int = 0, *,
             steps: int | None = None, render: str | Path | None = None, every: int = 4,
             act_timeout_s: float | None = DEFAULT_ACT_TIMEOUT_S, progress: bool = False) -> Episode:
    """Play one episode of ``policy`` on ``scenario``'s seed ``seed``; with ``render``, write it as an animated GIF.

    Args:
        policy: a registry name, a ``module:attr`` entry point or a policy object
            (anything :func:`~wfbench.harness.guard.load_policy` takes).
        scenario: a preset name, a suite's scenario id, a config file or a config
            (:func:`wfbench.scenario`, resolved once here).
        seed: the episode's seed.
        steps: stop after this many steps (default: the whole horizon).
        render: write an animated GIF of the episode here (its folder must exist).
        every: one frame every this many steps (with ``render``).
        act_timeout_s: the time limit of each ``reset`` and ``act`` call of a user's policy
            in seconds; ``None`` or 0 for no limit.
        progress: show a progress bar.

    Returns:
        The episode: steps played, the mean of each KPI, the frames written.

    Raises:
        ValueError: an unknown scenario, a bad number, a folder of ``render`` that does not
            exist; :class:`~wfbench.harness.guard.PolicyLoadError` (a ValueError) for a spec
            that names no policy.
        wfbench.harness.guard.PolicyError: a user's policy raised, hung past its act timeout
            or returned a malformed action.
    """
    from tqdm.auto import tqdm

    config = resolve_scenario(scenario)
    for name, value, least in (("seed", seed, 0), ("steps", steps, 1), ("every", every, 1)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least):
            raise ValueError(f"{name} = {value!r} is not allowed; allowed: an integer >= {least}")
    out = Path(render) if render is not None else None
    if out is not None and not out.parent.is_dir():
        raise ValueError(f"render {str(render)!r}: folder {str(out.parent)!r} does not exist")
    loaded = load_policy(policy, act_timeout_s)
    pol, guard = loaded.policy, loaded.guard
    sim = Simulator(config, [seed])
    obs = sim.reset()
    if guard is None:  # a built-in: our own code runs as it is
        if getattr(pol, "reads_trace", False):  # a hindsight oracle: handed the scenario, so the future
            pol.attach(sim.config)
        pol.reset([seed])
    else:
        if getattr(pol, "reads_trace", False):
            guard.call("attach", pol.attach, sim.config)
        guard.call("reset", pol.reset, [seed])
    renderer = None
    if out is not None:
        from wfbench.envs.render import Renderer

        renderer = Renderer(config)  # one figure for every frame (wfbench/envs/render.py)
    frames = [renderer.frame(sim)] if renderer else []
    limit = min(steps or config.horizon, config.horizon)
    with tqdm(total=limit, desc=f"simulate {config.name} seed {seed}", unit="step", leave=False,
              disable=not progress) as bar:
        while not sim.done and sim.t < limit:
            if guard is None:
                sim.step(pol.act(obs))
            else:
                guard.step(sim, guard.call("act", pol.act, obs), pol.act)
            obs = sim.observe()
            if renderer and sim.t % every == 0:
                frames.append(renderer.frame(sim))
                bar.set_postfix(frames=len(frames), refresh=False)
            bar.update(1)
    means = sim.episode_means()
    if out is not None:
        from wfbench.envs.render import save_gif

        save_gif(frames, out)
    return Episode(scenario=config, seed=seed, policy=loaded.name, steps=sim.t,
                   kpis={k: float(means[k][0]) for k in KPI_NAMES}, frames=len(frames), gif=out)
