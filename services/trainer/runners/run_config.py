"""What one training run is: its stage and environments, the policy architecture, how many
samples each update learns from, its budgets and where it writes (`RunConfig`, the flags of
`hamnet trainer`). Every other piece of a run (sources, runner, evaluation) reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from hamnet.perception.checkpoint import SHIPPED_ENCODER
from hamnet.policy.config import Initialization, LogStdConfig
from hamnet.policy.registry import architecture
from hamnet.runtime.compute import Precision
from hamnet.safety.config import ActionSpace
from hamnet.sim.config import SimConfig
from hamnet.sim.stages import STAGES, StageName, stage_config
from hamnet.trainer.config import GuideConfig, PPOConfig

NUM_ENVS = 64
"""Environments of a run unless `--sim.num-envs` says otherwise."""


def stage_sim(stage: StageName) -> SimConfig:
    """The environments of a run on `stage`: the stage with `NUM_ENVS` environments."""
    return stage_config(stage, num_envs=NUM_ENVS)


@dataclass(frozen=True)
class RunConfig:
    """One training run in one process."""

    stage: StageName = "easy"
    """Training stage (`hamnet.sim.stages`): full, easy or easy-5cm (the former easy stage).
    It sets the defaults of every `--sim.*` flag; those flags change any field on top of it."""
    sim: SimConfig = field(default_factory=lambda: stage_sim("easy"))
    """The environments: count (`--sim.num-envs`, default 64), seed of the sim, the networks
    and the action noise (`--sim.seed`), physics threads without `overlap`
    (`--sim.nthread`), scenes, placement, task and curriculum: the stage's, with any change."""
    architecture: str = "hamnet"
    """Policy architecture (`hamnet policy --print-params` lists them)."""
    action_space: ActionSpace = "joint"
    """What the policy's residual components ask for (`ActionMagnitudeConfig.space`):
    "joint" residuals (the paper's) or "paddle", the paddle's twist. The weights carry it
    (`ModelConfig.action_space`), so every filter that serves them reads them the same way;
    rollout workers take the same flag. DAgger's student acts in its teacher's space."""
    workers: int = 1
    """Rollout workers (`hamnet rollout`) whose chunks make one update, `--sim.num-envs`
    environments each (1 in-process). A trainer's own: its workers act as many steps as its
    announcements ask (`WeightsAnnouncement.rollout_steps`)."""
    samples_per_update: int = 8192
    """Env transitions each update learns from, T x environments x workers: the authors'
    1024 environments x 8 steps (rss_train.yaml:10, 166). It sets T unless
    `--steps-per-rollout` does: at 64 environments T = 128. Tied to the environment count
    (64 x 8 = 512), two independent batches' actor gradients agree at cosine 0.01-0.03 and
    each update spends its KL on noise (docs/trainer-history.md)."""
    steps_per_rollout: int = 0
    """T: policy steps per environment between two updates; 0: samples_per_update /
    (environments x workers). The authors' `rollout_size: 8` (rss_train.yaml:166, the
    paper's "update frequency 8") is their 8192 samples at 1024 environments."""
    max_env_transitions: int = 2_048_000_000
    """Stop after this many env_transitions (the authors' 2e6 vectorized steps of 1024)."""
    max_wall_clock_s: float = math.inf
    """Stop after this much wall-clock time over every resume, s: the iteration under way
    when it runs out is dropped, so the run's checkpoint and `wall_clock_s` lie within it."""
    run_dir: Path = Path("runs/train")
    """Where metrics.jsonl and checkpoints go."""
    encoder_checkpoint: Path = SHIPPED_ENCODER
    """UniCORN weights, frozen while the policy learns (the paper's); default: the
    pre-trained encoder shipped in the package."""
    random_encoder: bool = False
    """Freeze a randomly initialised encoder (version 0) instead: the ablation without
    pre-training."""
    encoder_precision: Precision = "auto"
    """How the encoder's layers run while the run acts (`CloudConfig.encoder_precision`):
    "auto" is bfloat16 on a CPU with native bfloat16; float32 for tokens exactly as before."""
    overlap: bool | None = None
    """Split the environments into two groups and step one group's physics while the other's
    perception, policy and safety run (`rollout.collect_overlapped`), so both cores stay
    busy; None: when the policy reads clouds (1.18x for HAMnet at 64 environments in
    `benchmarks/training.py`; a policy without perception is faster on all physics threads)."""
    learner_threads: int = 0
    """Torch threads of the PPO update; 0: when the environments wait for it (in process, or
    synchronous workers, `--max-policy-lag` 0), every core, shared among learner ranks
    (1.6-1.8x faster updates than one thread on the 2-core machine, `benchmarks/learner.py`);
    else 1. Set 1 where other services share the cores: the demo's stack of seven services
    on 2 cores ran its tiny updates too slowly with two threads."""
    log_period_s: float = 10.0
    """Seconds between two progress lines."""
    checkpoint_period_s: float = 600.0
    """Seconds between two checkpoints (one more is written at the end)."""
    eval_episodes: int = 64
    """Held-out episodes the final policy plays with its mean (`final_success_rate`); 0: none."""
    ppo: PPOConfig = field(default_factory=PPOConfig)
    guide: GuideConfig = field(default_factory=GuideConfig)
    """PPO's guide: the scripted pusher's actions as an imitation target, weighted
    `--guide.coef` until `--guide.hold` transitions, then falling to 0 at `--guide.until`;
    off by default (`GuideConfig`)."""
    init: Initialization = "orthogonal"
    """How the actor and critic start: orthogonal (output layers 0.01 and 1) or torch's
    default, the authors' (`hamnet.policy.init`)."""
    shared_value_gradient: bool = False
    """HAMnet: the value loss trains the layers actor and critic share too (the authors');
    default: the critic reads them with their gradient stopped
    (`ModelConfig.shared_value_gradient`, docs/trainer.md)."""
    pose_readings: int = 1
    """A student architecture: the object pose it reads is the mean of its estimator's last
    this many readings in the episode (`ModelConfig.pose_readings`; 4 lifted the easy-push
    teacher from 0.410 on one reading to 0.523, issue 28). The weights carry it."""
    log_std: LogStdConfig = field(default_factory=LogStdConfig)
    """The actor's log std: learned from -0.5 (default), or a schedule over env_transitions
    (`--log-std.mode schedule`: the authors' -0.4 minus 0.000367 per 1024 x 1024
    transitions, which spans their 2e9; `--log-std.horizon N` shrinks it to
    `--log-std.final` within N transitions). The weights carry it to every policy that acts."""

    @property
    def overlapped(self) -> bool:
        """Whether the run collects in two overlapped groups (`overlap`, resolved)."""
        if self.overlap is None:
            return architecture(self.architecture).config.clouds
        return self.overlap

    @property
    def num_envs(self) -> int:
        """B: environments stepped together (the sim's)."""
        return self.sim.num_envs

    @property
    def rollout_steps(self) -> int:
        """T of every rollout: `steps_per_rollout`, or derived from `samples_per_update`."""
        if self.steps_per_rollout:
            return self.steps_per_rollout
        return max(1, self.samples_per_update // (self.num_envs * self.workers))

    @property
    def seed(self) -> int:
        """Seed of the sim, the networks and the action noise (the sim's)."""
        return self.sim.seed

    @property
    def identity(self) -> dict[str, object]:
        """What a resumed run must share with its snapshot: the networks' shapes, the
        environments and the rollout length (the PPO settings and budgets may change)."""
        return {
            "architecture": self.architecture,
            "action_space": self.action_space,
            "sim": self.sim,
            "steps_per_rollout": self.rollout_steps,
            "overlapped": self.overlapped,
        }

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"unknown stage {self.stage!r}; stages: {', '.join(STAGES)}")
        if self.steps_per_rollout < 0 or self.samples_per_update < 1 or self.workers < 1:
            raise ValueError("steps_per_rollout must be >= 0, samples_per_update and workers >= 1")
        if self.overlapped and self.num_envs % 2:
            raise ValueError("overlap splits the environments in two groups: num_envs must be even")
        if self.eval_episodes < 0 or self.learner_threads < 0:
            raise ValueError("eval_episodes and learner_threads must be >= 0")
        if self.pose_readings < 1:
            raise ValueError(f"pose_readings must be >= 1, got {self.pose_readings}")
        if self.pose_readings > 1 and architecture(self.architecture).config.privileged:
            raise ValueError(
                f"--pose-readings averages a student's pose estimate; {self.architecture} "
                "reads the true pose (use a student architecture, or 1)"
            )
