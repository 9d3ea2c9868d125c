"""A training run's settings: :class:`BaseConfig` (every trainer's) and :class:`ActorCriticConfig` on it.

Each algorithm's config subclasses one of them and adds only its own fields and checks
(``check``); :func:`check_ints` and :func:`check_numbers` word a bad value the one way.
:func:`network_config` and :func:`build_model` make the network a config names
(``docs/rl.md``, "The trainers").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields

import torch

from wfbench.core.config import ScenarioConfig
from wfbench.core.seeds import SEED_SETS, resolve_seeds
from wfbench.policies.neural import scalefree
from wfbench.policies.neural.model import AgentSet, WorkforceNet, model_config
from wfbench.scenarios.resolve import resolve_scenario
from wfbench.train.worlds import WorldSet, world_set

DECISIONS = ("dispatch", "workforce", "positioning")  # the heads of the joint network, in the simulator's order
DEVICES = ("auto", "cpu", "cuda")


def check_ints(cfg, names: Sequence[str], least: int = 1) -> None:
    """Each of ``names`` an integer (not a bool) >= ``least``, else a ValueError naming what is allowed."""
    for name in names:
        v = getattr(cfg, name)
        if type(v) is not int or v < least:
            raise ValueError(f"{name} = {v!r} is not allowed; allowed: an integer >= {least}")


def check_numbers(cfg, names: Sequence[str], ok: Callable[[float], bool], allowed: str) -> None:
    """Each of ``names`` passes ``ok``, else a ValueError: ``NAME = V is not allowed; allowed: ALLOWED``."""
    for name in names:
        if not ok(getattr(cfg, name)):
            raise ValueError(f"{name} = {getattr(cfg, name)!r} is not allowed; allowed: {allowed}")


@dataclass
class BaseConfig:
    """The settings every trainer has; saved as ``config.json`` in the run directory and in each checkpoint.

    An algorithm's config subclasses it (or :class:`ActorCriticConfig`), adds its own
    fields (and may give a field another default) and its own checks in :meth:`check`.
    """

    scenario: str = "paper-64"
    scenarios: str = ""  # several worlds (wfbench.train.worlds): e.g. "suite-v1:train"; when set, scenario is unused
    variant: str = "joint"
    model: str = "small"  # wfbench.policies.neural.model.PRESETS
    steps: int = 1_000_000  # environment steps in all (B per simulator step)
    num_envs: int = 32  # B
    num_steps: int = 32  # T: steps per rollout (or stored sequence)
    seed: int = 0
    device: str = "auto"  # auto | cpu | cuda
    bf16: bool = True  # CUDA only: bf16 autocast of the forward passes
    threads: int = 1  # torch CPU threads (the simulator uses numba's)
    checkpoint_every: int = 20  # updates (iterations)
    eval_every: int = 20  # updates (iterations); 0: never
    eval_seeds: str = "public:10"  # a part of the public set: checkpoint selection only
    run_dir: str = "runs/ppo"
    init: str = ""  # a checkpoint whose network weights start this run (fine-tuning); nothing else is taken
    model_overrides: dict = field(default_factory=dict)
    scalefree_ok = False  # a class attribute, not a setting: whether this trainer trains the scale-free network
    # a class attribute too: the environments per world of a batch that holds every world (--scenarios), when
    # --num-envs is not given; None for a trainer whose batches take the worlds in turn (num_envs as given)
    envs_per_world = None

    def validate(self) -> ScenarioConfig | WorldSet:
        """The shared checks, the algorithm's (:meth:`check`), then the network's config (a bad preset says so).

        Returns:
            The scenario, resolved (once: :func:`wfbench.train.record.start_run` keeps it), or the
            :class:`WorldSet` of ``scenarios``.
        """
        if self.device not in DEVICES:
            raise ValueError(f"device {self.device!r} is not allowed; allowed: {', '.join(DEVICES)}")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device 'cuda' asked for, but torch sees no CUDA device (use --device cpu or auto)")
        check_ints(self, ("steps", "num_envs", "num_steps", "threads", "checkpoint_every"))
        check_ints(self, ("eval_every",), least=0)
        if self.model == scalefree.ARCH and not self.scalefree_ok:
            raise ValueError(f"model 'scalefree' is not trained by {type(self).__module__.rsplit('.', 1)[-1]}; "
                             "allowed: --algo ppo, impala or hindsight (or a model preset: tiny, small, paper, cpu)")
        self.check()
        if self.scenarios:
            scenario = world_set(self.scenarios)
            if self.variant != "joint":
                raise ValueError(f"scenarios {self.scenarios!r} with variant {self.variant!r}: training across worlds "
                                 "is for the joint network; allowed: variant joint")
        else:
            scenario = resolve_scenario(self.scenario)
        if not set(resolve_seeds(self.eval_seeds)) <= set(SEED_SETS["public"]):
            raise ValueError(f"eval_seeds {self.eval_seeds!r}: checkpoints are selected on the public seeds "
                             "(1000-1049) only, never on test seeds")
        self.network_config()
        return scenario

    def check(self) -> None:
        """The algorithm's own checks (a subclass's); ValueError names what is allowed."""

    def network_config(self):
        """The network's config: the joint network with all three heads (PPO's variants and agents differ)."""
        return network_config(self.model, DECISIONS, self.model_overrides)

    @classmethod
    def from_dict(cls, d: dict):
        """The config of a saved ``train_config`` (keys this class does not have are dropped)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


@dataclass
class ActorCriticConfig(BaseConfig):
    """The settings PPO and IMPALA share: the reward shaping of the collector, and the loss coefficients.

    The collector is :class:`wfbench.train.collection.Collector`.
    """

    lr: float = 3e-4
    gamma: float = 0.995
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    reward_offset: float = 0.7  # reward = (NSW_t - offset) * scale
    reward_scale: float = 10.0
    normalize_returns: bool = True  # rewards divided by a running std of the discounted return
    stagger: bool = True  # staggered episodes by partial reset

    def validate(self) -> ScenarioConfig | WorldSet:
        check_numbers(self, ("gamma",), lambda v: 0.0 < v <= 1.0, "a number in (0, 1]")
        check_numbers(self, ("lr", "max_grad_norm"), lambda v: v > 0.0, "a number > 0")
        check_numbers(self, ("ent_coef", "vf_coef", "reward_scale"), lambda v: v >= 0.0, "a number >= 0")
        return super().validate()


def network_config(preset: str, decisions: tuple[str, ...], overrides: dict):
    """The config of network ``preset``: one of :data:`wfbench.policies.neural.model.PRESETS` or ``scalefree``."""
    if preset == scalefree.ARCH:
        return scalefree.scalefree_config(decisions, **overrides)
    return model_config(preset, decisions, **overrides)


def build_model(network, independent: bool = False) -> torch.nn.Module:
    """A fresh network (on CPU) for a run's config (:func:`network_config`).

    The scale-free network for an observation-version-2 config (``ScaleFreeConfig``), else the
    paper's: ``AgentSet`` (one network per decision) when ``independent``, ``WorkforceNet``
    otherwise.
    """
    if getattr(network, "obs_version", 1) == 2:
        return scalefree.ScaleFreeNet(network)
    return AgentSet(network) if independent else WorkforceNet(network)
