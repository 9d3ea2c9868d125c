"""Learned policies: the paper's joint network (torch), its action distributions and checkpoints as policies.

Importing this package imports no torch (its modules do); ``import policies`` does not
import it, and ``policies.get("ppo:path/to/ckpt.pt")`` imports it on first use.
``docs/rl.md`` has the model and the trainers (``wfbench.train``, one module per
algorithm), and the shipped checkpoints (``policies/neural/checkpoints/``), registered below
(:mod:`wfbench.policies.table`).
"""

from wfbench.policies.table import SINCE_V1, SINCE_V2, SINCE_V3, Checkpoint, Entry, register

# the algorithms a checkpoint can name in its ``algo`` key, each its prefix ``ALGO:PATH``
# (wfbench.train.registry.ALGORITHMS; tests/train/test_train_registry.py checks the two agree)
CHECKPOINT_ALGORITHMS = ("ppo", "impala", "hindsight", "distill")
ALIAS = "ppo"  # the prefix that loads a checkpoint of any algorithm (the one every checkpoint loaded by before)

# the trained networks shipped in policies/neural/checkpoints/, by name (docs/rl.md; wfbench.policies.table), each
# named by the algorithm that trained it (its checkpoint's algo key: no key is ppo); a name is offered only when its
# file is there, and loading it needs torch (the rl extra). A network has no decision names to take its table labels
# from, so each says what decides (PPO, hindsight learning, or both). The generalists list their training seeds'
# files (issue #28, docs/suite.md "Learned methods over training seeds"): the shipped file is a byte copy of the
# median seed's (wfbench.analysis.aggregate.median_seed); the oracle plays the shipped pick only
register(
    Entry("ppo-joint", "learned", Checkpoint("ppo-joint-paper-64.pt"),
          "the joint PPO network (all three decisions) trained on paper-64",
          decisions=("PPO", "PPO", "PPO"), candidate_of=SINCE_V1),
    Entry("ppo-dispatch", "learned", Checkpoint("ppo-dispatch-paper-64.pt"),
          "the dispatch-only PPO network trained on paper-64, heuristic workforce and positioning",
          decisions=("PPO", "Heuristic", "Heuristic"), candidate_of=SINCE_V1),
    Entry("impala-joint", "learned", Checkpoint("impala-joint-paper-64.pt"),
          "the joint network trained with IMPALA (V-trace) on paper-64",
          decisions=("IMPALA", "IMPALA", "IMPALA"), candidate_of=SINCE_V1),
    Entry("hindsight-joint", "learned", Checkpoint("hindsight-joint-paper-64.pt"),
          "the joint network trained by imitating the hindsight oracles (DAgger) on paper-64",
          decisions=("Hindsight learning",) * 3, candidate_of=SINCE_V1),
    Entry("ppo-independent", "learned", Checkpoint("ppo-independent-paper-64.pt"),
          "three PPO networks, one per decision (independent agents), trained together on paper-64",
          decisions=("PPO (own net)",) * 3, candidate_of=SINCE_V1),
    Entry("hindsight-ppo", "learned", Checkpoint("hindsight-ppo-paper-64.pt"),
          "ppo-joint with its workforce head improved by hindsight learning on its own action values (the known "
          "future, its own policy acting) on paper-64",
          decisions=("PPO", "PPO + hindsight learning", "PPO"), candidate_of=SINCE_V1),
    Entry("ppo-general", "learned",
          Checkpoint("ppo-general.pt", seeds=tuple(f"ppo-general-seed{i}.pt" for i in range(5))),
          "the joint PPO network trained across suite-v1's eight training scenarios (from ppo-joint's weights); the "
          "median of 5 training seeds (ppo-general#seedK)",
          decisions=("PPO (generalist)",) * 3, candidate_of=SINCE_V1),
    Entry("hindsight-general", "learned",
          Checkpoint("hindsight-general.pt", seeds=tuple(f"hindsight-general-seed{i}.pt" for i in range(5))),
          "ppo-general with its workforce head improved by hindsight learning on its own action values across the "
          "training scenarios; the median of 5 seeds",
          decisions=("PPO (generalist)", "PPO + hindsight learning (generalist)", "PPO (generalist)"),
          candidate_of=SINCE_V1),
    Entry("scalefree-general", "learned",
          Checkpoint("scalefree-general.pt", seeds=tuple(f"scalefree-general-seed{i}.pt" for i in range(5))),
          "the scale-free network (observation version 2: lengths in travel time, the world's parameters as context) "
          "trained by PPO from scratch across suite-v1's eight training scenarios; the median of 5 training seeds",
          decisions=("PPO (scale-free)",) * 3, candidate_of=SINCE_V2),
    # issue #52: scalefree-general's workforce and positioning heads trained to imitate its own search on the
    # network's states (DAgger, wfbench train --algo distill; docs/rl.md "Distillation"); shipped after v2, so that
    # shipping it moved no published number; a candidate from v3 on
    Entry("distill-general", "learned",
          Checkpoint("distill-general.pt", seeds=tuple(f"distill-general-seed{i}.pt" for i in range(5))),
          "scalefree-general with its workforce and positioning heads distilled from its search "
          "(search-scalefree-general) across the training scenarios; the median of 5 training seeds",
          decisions=("PPO (scale-free)", "search distilled (scale-free)", "search distilled (scale-free)"),
          candidate_of=SINCE_V3),
    # issue #52: scalefree-general trained to imitate switch-scalefree-general (its five training seeds chosen on
    # sampled futures) on the network's own states, all three heads (docs/rl.md "Distilling the switch"); shipped
    # after v3's candidates were fixed: no reference plays it
    Entry("distill-switch-general", "learned",
          Checkpoint("distill-switch-general.pt", seeds=tuple(f"distill-switch-general-seed{i}.pt" for i in range(5))),
          "scalefree-general distilled from the switch among its training seeds (switch-scalefree-general) across "
          "the training scenarios, all three heads; the median of 5 training seeds",
          decisions=("switch distilled (scale-free)",) * 3),
)
