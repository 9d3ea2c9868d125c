"""Every checkpoint records the algorithm that trained it and loads as a policy by it (wfbench.train.registry)."""

from __future__ import annotations

import pytest
import torch
from wfbench.policies.neural import ALIAS, CHECKPOINT_ALGORITHMS
from wfbench.policies.registry import checkpoint_file

from wfbench import policies
from wfbench.train.config import BaseConfig
from wfbench.train.impala import ImpalaConfig
from wfbench.train.impala import Trainer as ImpalaTrainer
from wfbench.train.ppo import TrainConfig
from wfbench.train.ppo import Trainer as PPOTrainer
from wfbench.train.registry import ALGORITHMS, DEFAULT_ALGORITHM, get_algorithm


def test_registry__names_configs_and_trainers_agree_with_the_checkpoint_prefixes():
    assert tuple(ALGORITHMS) == CHECKPOINT_ALGORITHMS and DEFAULT_ALGORITHM == ALIAS == "ppo"
    for name, algo in ALGORITHMS.items():
        assert issubclass(algo.config_class(), BaseConfig), name
        assert callable(algo.trainer_class().train), name
    with pytest.raises(ValueError, match="algorithm 'sac' is not known; allowed: ppo, impala, hindsight, distill"):
        get_algorithm("sac")


@pytest.mark.slow
def test_registry__a_checkpoint_records_its_algorithm_and_loads_by_its_prefix(tmp_path):
    run = tmp_path / "impala"
    tr = ImpalaTrainer(ImpalaConfig(scenario="small", model="tiny", num_envs=2, num_steps=8, steps=16, mode="sync",
                                    eval_every=1, eval_seeds="public:1", run_dir=str(run), seed=1),
                       progress=False, log=False)
    tr.train()
    best = run / "best.pt"
    assert torch.load(best, weights_only=False)["algo"] == "impala"
    pol = policies.get(f"impala:{best}")
    assert pol.name == f"impala:{best}" and set(pol.decisions) == {"dispatch", "workforce", "positioning"}
    assert policies.get(f"ppo:{best}@greedy").mode == "greedy"  # ppo: is the alias for any checkpoint
    with pytest.raises(ValueError) as err:
        policies.get(f"hindsight:{best}")
    msg = str(err.value)
    assert "\n" not in msg and "was trained by impala, not hindsight" in msg
    assert msg.endswith(f"allowed: impala:{best} or ppo:{best}")

    ppo_run = tmp_path / "ppo"
    PPOTrainer(TrainConfig(scenario="small", model="tiny", num_envs=2, num_steps=8, minibatches=1, steps=16,
                           eval_every=0, run_dir=str(ppo_run)), progress=False, log=False).train()
    assert torch.load(ppo_run / "latest.pt", weights_only=False)["algo"] == "ppo"
    assert policies.get(f"ppo:{ppo_run / 'latest.pt'}").name.startswith("ppo:")


def test_registry__shipped_checkpoints_load_by_their_algorithm_old_ones_without_algo_as_ppo():
    ppo = checkpoint_file("ppo-joint")
    if not ppo.is_file():
        pytest.skip("the shipped checkpoints are not in this checkout")
    assert "algo" not in torch.load(ppo, weights_only=False)  # written before the key existed: PPO's
    assert policies.get(f"ppo:{ppo}").name == f"ppo:{ppo}"
    with pytest.raises(ValueError, match=r"was trained by ppo, not impala; allowed: ppo:"):
        policies.get(f"impala:{ppo}")
    impala = checkpoint_file("impala-joint")
    assert policies.get(f"impala:{impala}").name == f"impala:{impala}"
    assert policies.get("ppo-joint").name == "ppo-joint" and policies.get("impala-joint").name == "impala-joint"
