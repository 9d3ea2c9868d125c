"""RLlib PPO on the three agents of the PettingZoo environment, one policy per agent (docs/envs.md).

RLlib (``pip install "ray[rllib]"``) is too heavy for the test suite, so this script is the
check: it trains a few iterations and prints each one's mean episode return. The only
wfbench-specific part is the environment's options: ``observation="box"`` (one float32
Box) and ``actions="shared"`` (every agent the same MultiDiscrete), the spaces RLlib's
default models take::

    python benchmarks/rllib_ppo.py --iterations 3 --scenario small

Its output, quoted in docs/envs.md, is the record that RLlib runs; ``--iterations 0`` only
builds the algorithm.
"""

from __future__ import annotations

import argparse
import time

import wfbench


def make_env(env_config: dict):
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    scenario = env_config.get("scenario", "small")
    return ParallelPettingZooEnv(wfbench.parallel_env(scenario, observation="box", actions="shared"))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=3)
    ap.add_argument("--scenario", default="small")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    import ray
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.tune.registry import register_env

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    register_env("wfbench-parallel", make_env)
    agents = wfbench.parallel_env(args.scenario).possible_agents
    config = (
        PPOConfig()
        .environment("wfbench-parallel", env_config={"scenario": args.scenario})
        .multi_agent(policies=set(agents), policy_mapping_fn=lambda agent_id, *a, **k: agent_id)
        .env_runners(num_env_runners=0, rollout_fragment_length=200)
        .training(train_batch_size_per_learner=400, minibatch_size=200, num_epochs=2)
        .debugging(seed=args.seed)
    )
    algo = config.build_algo()
    for i in range(args.iterations):
        start = time.perf_counter()
        result = algo.train()
        runners = result.get("env_runners", {})
        print(f"iteration {i + 1}: episode_return_mean {runners.get('episode_return_mean', float('nan')):.3f}, "
              f"env steps {runners.get('num_env_steps_sampled_lifetime', 0)}, {time.perf_counter() - start:.1f} s")
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
