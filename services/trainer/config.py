"""The trainer's hyperparameters, each with its source: PPO's, DAgger's, and which of the
two a run learns by (`AlgoConfig`).

Rule (docs/mdp.md): where the paper's Table tab:PPO and the authors' training configuration
disagree, the configuration wins (it produced the reported numbers) and the paper's value is
kept as the `paper` preset. "config" below means the authors' repository (iMSquared/HAMNet
at 36f8267): `rss_train.yaml` is `ham/src/ham/data/cfg/rss_train.yaml`, `ppo_config.py` is
`ham/src/ham/models/rl/ppo_config.py` (its defaults apply where the YAML is silent) and
`ppo.py` is `ham/src/ham/models/rl/v6/ppo.py`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, get_args

from hamnet.runtime.compute import Precision

KLStop = Literal["rollback", "before-step", "off"]
"""How an update stops on the KL of its policy from the acting one (`PPOConfig.kl_stop`)."""
LRSchedule = Literal["adaptive", "fixed"]
"""How the actor's learning rate moves between steps (`PPOConfig.lr_schedule`)."""


@dataclass(frozen=True)
class PPOConfig:
    """One PPO update: advantages, losses, epochs, early stopping and the learning rate."""

    gamma: float = 0.99
    """Discount (paper Table tab:PPO; config `ppo_config.py:49`)."""
    gae_lambda: float = 0.95
    """GAE's lambda (paper; config `ppo_config.py:50`)."""
    clip: float = 0.3
    """PPO ratio clip range (paper; config `ppo_config.py:51`)."""
    epochs: int = 8
    """Most passes over a rollout per update (paper "Max Num. epoch"; `rss_train.yaml:179`)."""
    minibatches: int = 4
    """Gradient steps per epoch, each on a random 1/minibatches of the batch. Ours: 4, so
    that each of the 8192 samples (`RunConfig.samples_per_update`) is seen in minibatches of
    2048, where two independent batches' actor gradients still agree (cosine 0.1 at 2048
    against 0.01-0.03 at 512, measured on the easy stage, docs/trainer.md); the authors step
    once per epoch on their whole 8192-sample rollout (`accumulate_gradient: 1`,
    `rss_train.yaml:180`; `ppo.py:607-611`: preset `authors`)."""
    lr: float = 3e-4
    """Base learning rate of Adam (paper; config `ppo_config.py:132`)."""
    kl_target: float = 0.016
    """Target of the KL-adaptive learning rate (paper; `rss_train.yaml:178`)."""
    kl_bounds: tuple[float, float] = (0.5, 2.0)
    """The rate grows below kl_bounds[0] * kl_target and shrinks above kl_bounds[1] *
    kl_target (config `ppo_config.py:88`, rule in `ham/src/ham/models/rl/adaptive_lr.py`)."""
    lr_factor: float = 1.5
    """Factor of each learning-rate change (config `ppo_config.py:89`)."""
    lr_bounds: tuple[float, float] = (1e-6, 1e-2)
    """The adapted learning rate stays in this range (config `ppo_config.py:90`)."""
    early_stop_factor: float = 1.5
    """The update stops once the KL exceeds early_stop_factor * kl_target: 0.024, the
    paper's "early-stopping KL target" (config `ppo.py:570-571`)."""
    kl_stop: KLStop = "rollback"
    """rollback: after every step the KL of the policy it made is measured (on the next
    minibatch, which that step did not fit, or on a fresh one after the last step); a step
    past the bound is undone and the update ends, so the KL an update ends at is within the
    bound. before-step: the authors' check before each step after the first, which keeps
    the step that overshot (their `_train_batch`, `ppo.py:567-596`: measured 2-4x the
    bound). off: every epoch runs (CleanRL, rsl_rl)."""
    lr_schedule: LRSchedule = "fixed"
    """fixed: the actor's rate stays at `lr` (CleanRL; the outside anchor of issue 27);
    adaptive: it follows the KL of each step (`adaptive_lr.py`, preset `authors`). Measured
    on the easy stage with 2048-sample minibatches (state MLP, first 0.15 M transitions):
    adaptive climbs to 1.5e-3-2.3e-3 and the update stops after 1-2 of its 32 steps, so
    each update follows two minibatches' gradients, whose halves agree at cosine 0.0-0.1;
    fixed at 3e-4 keeps 7-18 steps over every minibatch, averaging that noise, at the same
    KL (0.019-0.023)."""
    value_lr: float | None = 3e-4
    """Learning rate of the critic's own parameters (a second param group of the optimizer,
    neither adapted to the actor's KL nor stopped with it: once the actor stops, the critic
    goes on through the remaining epochs). None: the critic shares the actor's group, rate
    and stop, as the authors' single optimizer does. 3e-4: PPO's base rate (paper)."""
    clip_per_term: bool = False
    """True: the authors' clipping, min(r A_i, clip(r) A_i) per reward term, then summed
    (`ppo_util.py` with per-term advantages): once ratios clip, any term whose sign
    disagrees pulls back. False: textbook PPO on the summed advantage."""
    policy_coef: float = 0.5
    """Weight of the clipped-surrogate loss: config `ppo_config.py:65` (the paper's table
    says 2; the two coefficients appear swapped there)."""
    value_coef: float = 2.0
    """Weight of the value loss, 0.5 * mean squared error (`rss_train.yaml:172`; paper 0.5)."""
    bound_coef: float = 0.02
    """Weight of the bound loss on the action mean (paper; `rss_train.yaml:171`)."""
    bound_scale: float = 1.1
    """The bound loss penalises a mean outside 1.1x the action bounds (config
    `ham/src/ham/models/rl/ppo_util.py`, `get_bound_loss(scale=1.1)`)."""
    energy_coef: float = 0.0
    """Weight of the energy loss (`losses.energy_loss`): 0, off, as the authors train
    (`use_energy_loss: False`, `ppo.py:101`); their coefficient when on is 5e-5
    (`ppo_config.py:69`), the paper's table says 8e-5."""
    normalize_advantages: bool = True
    """Advantages centred per term and scaled by the standard deviation of their sum
    (config `ppo_config.py:55`; `ppo_util.py` `_ppo_loss_and_logs`, `SUM_REW`)."""
    max_grad_norm: float = 1.0
    """Gradient clipping by norm (config `ppo.py:98`), per optimizer group: with the
    critic's own group (`value_lr`) the actor's and the critic's gradients are clipped
    apart, so a large value gradient does not shrink the actor's step (on HAMnet it cut
    every actor step to 40%, `ModelConfig.shared_value_gradient`); one group: the global
    norm, as the authors."""
    precision: Precision = "auto"
    """How the update's network passes run (`hamnet.runtime.compute.Precision`): bfloat16
    runs them under bfloat16 autocast (the distribution, log-probabilities, losses and
    parameters stay float32); "auto" does so on a CPU with native bfloat16, float32
    elsewhere. Ours, measured: the update 1.65x faster on 8192 HAMnet samples
    (`benchmarks/learner.py`, gradient cosine 1.000 against float32's), and HAMnet learned
    the same side by side (docs/results/ppo-bfloat16.json)."""

    def __post_init__(self) -> None:
        for name in ("gamma", "gae_lambda"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not self.energy_coef >= 0.0:
            raise ValueError(f"energy_coef must be >= 0, got {self.energy_coef}")
        if self.value_lr is not None and not self.value_lr > 0:
            raise ValueError(f"value_lr must be > 0 or None, got {self.value_lr}")
        for name in ("clip", "lr", "kl_target", "max_grad_norm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.precision not in get_args(Precision):
            raise ValueError(
                f"precision must be one of {get_args(Precision)}, got {self.precision!r}"
            )
        if self.epochs < 1 or self.minibatches < 1:
            raise ValueError("epochs and minibatches must be >= 1")
        if not self.lr_bounds[0] <= self.lr <= self.lr_bounds[1]:
            raise ValueError(f"lr {self.lr} outside lr_bounds {self.lr_bounds}")
        if not (0 < self.kl_bounds[0] < 1 < self.kl_bounds[1] and self.lr_factor > 1):
            raise ValueError("kl_bounds must straddle 1 and lr_factor must be > 1")


@dataclass(frozen=True)
class GuideConfig:
    """PPO's guide (ours; the paper's PPO has none): an imitation term that pulls the policy's
    mean towards the scripted pusher's action (`hamnet.trainer.collection.scripted_pusher`)
    in every state the rollout acted in, its weight held, then falling linearly to 0, after
    which PPO goes on alone. The pusher reads the true state, which the policy's inputs
    carry (the teacher's object pose and the object's cloud), so a policy can learn what it
    does; then PPO's own gradient has successes to work from. Measured on the easy stage in
    the paddle space (docs/trainer-history.md, "A scripted guide"): HAMnet's mean imitating
    the pusher alone reached 0.363 held-out success after 0.25 M transitions, against 0.06
    for PPO alone; the state MLP, which does not see the object's size, 0.121. Rollout
    workers label states only when `coef` > 0 (the policy service's rollouts carry no
    labels, so a guided run learns from workers or in process)."""

    coef: float = 0.0
    """Weight of the imitation term (mean squared error of the action mean against the
    pusher's raw action, over its components) while held; 0: no guide."""
    hold: int = 0
    """env_transitions during which the weight stays at `coef`."""
    until: int = 0
    """env_transitions at which the weight, falling linearly after `hold`, reaches 0."""

    def weight(self, env_transitions: int) -> float:
        """The imitation term's weight at the schedule counter `env_transitions`."""
        if env_transitions <= self.hold:
            return self.coef
        if env_transitions >= self.until:
            return 0.0
        return self.coef * (self.until - env_transitions) / (self.until - self.hold)

    def __post_init__(self) -> None:
        if self.coef < 0:
            raise ValueError(f"guide coef must be >= 0, got {self.coef}")
        if self.coef and not 0 <= self.hold <= self.until:
            raise ValueError(f"a guide needs 0 <= hold <= until, got {self.hold}, {self.until}")


AUTHORS = PPOConfig(
    minibatches=1, kl_stop="before-step", lr_schedule="adaptive", value_lr=None, clip_per_term=True
)
"""The authors' update as their configuration runs it on 1024 GPU environments."""

PPO_PRESETS: dict[str, PPOConfig] = {
    "small-scale": PPOConfig(),
    "authors": AUTHORS,
    "paper": replace(AUTHORS, policy_coef=2.0, value_coef=0.5),
}
"""Ours at a few CPU environments (default), the authors' configuration, and the paper's
Table tab:PPO where it differs from that."""


@dataclass(frozen=True)
class DaggerConfig:
    """Beta's schedule and the student's update. Neither the paper nor the authors give
    DAgger settings; these are ours."""

    beta_initial: float = 1.0
    """Probability that the teacher acts an episode at the start: 1, DAgger's first
    iteration (the teacher alone), so the student first learns on the teacher's states."""
    beta_final: float = 0.0
    """... and once the decay is over: 0, the student alone, the deployed situation, so the
    late data are the states the student itself drifts into."""
    beta_decay_transitions: int = 200_000
    """env_transitions over which beta falls linearly from `beta_initial` to `beta_final`:
    about a third of an hour's run on this machine (roughly 150 env steps/s with two
    perceptions), so most of the run trains on the student's own states."""
    epochs: int = 4
    """Gradient steps per rollout, each on the whole (T, B) window (as PPO's one minibatch
    per epoch): a few, since the window is small and the next one comes from similar states."""
    lr: float = 3e-4
    """Adam's learning rate at the start: PPO's base rate (paper Table tab:PPO)."""
    lr_final: float = 3e-5
    """... and once `lr_decay_transitions` are done (linear in between; equal to `lr`:
    constant). The student is judged by its last weights, which its last steps at the full
    rate, fitted to its newest windows, displace: at a tenth of the rate the same updates
    fitted the student's own states (loss 0.0067 against 0.0103) and raised its held-out
    success from 0.305 to 0.344 (`scripts/student_fit.py`, docs/trainer.md)."""
    lr_decay_transitions: int = 300_000
    """env_transitions over which the rate falls from `lr` to `lr_final`: a 40-minute run
    on this 2-core machine (140 env steps/s with two perceptions and the replay)."""
    max_grad_norm: float = 1.0
    """Gradient clipping by global norm: PPO's (authors' `ppo.py:98`)."""
    replay_windows: int = 128
    """Windows the update learns from: the newest and up to N - 1 before it, the states the
    last N students visited (DAgger's aggregated dataset, Ross et al. 2011, bounded by
    memory: a window of 64 environments x 8 steps keeps 10.7 MB, so 1.4 GB, the last
    0.065 M transitions); 1: the newest only. With these defaults the guided teacher's
    student reached 0.91 of it, against 0.77 with the newest window and a constant rate
    (docs/results/dagger-easy-guided-replay.json)."""
    replay_draw: int = 1
    """Older windows merged with the newest one at each of `epochs` steps, drawn at random
    (without replacement, anew each step) from the kept ones: each step costs (1 + draw)
    windows' unroll (one: the update took 1.8 s a window here against 1.2 s, 140 env
    steps/s against 164)."""
    value_coef: float = 0.0
    """Weight of the value loss (0.5 x squared error to the teacher's values per reward
    term); 0: off. The deployed student needs no critic; on, it gives the student a critic
    for fine-tuning by PPO later."""
    velocity_coef: float = 0.0
    """Weight of the velocity loss (`dagger.VelocityReadout`: the object's true velocity
    read linearly from the student's memory, squared error in the teacher's standardised
    units); 0: off, no read-out. The teacher relies on the object's velocity and the student
    must infer it from pose estimates (`scripts/teacher_privileged.py`); on, the loss asks
    its memory to hold it."""
    weight_average: float = 0.0
    """Decay of an exponential moving average of the student's weights, once per window;
    0: off. On, the optimizer steps a copy of the student and the run's student (what acts,
    is published, checkpointed and evaluated) is the average of that copy's recent weights,
    so a window's noisy step moves it by a part only: two fits of the same windows held out
    0.336 and 0.426 (`scripts/student_fit.py` on the easy-push student, issue 28), their
    gradients between windows at cosine 0.30. 0.99 averages about the last 100 windows,
    the span of the default replay (ours)."""

    def __post_init__(self) -> None:
        for name in ("beta_initial", "beta_final"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.beta_decay_transitions < 0 or self.epochs < 1:
            raise ValueError("beta_decay_transitions must be >= 0 and epochs >= 1")
        if self.replay_windows < 1 or self.replay_draw < 0:
            raise ValueError("replay_windows must be >= 1 and replay_draw >= 0")
        if not (self.lr > 0 and self.lr_final > 0 and self.max_grad_norm > 0):
            raise ValueError("lr, lr_final and max_grad_norm must be > 0")
        if self.lr_decay_transitions < 0:
            raise ValueError("lr_decay_transitions must be >= 0")
        if not (self.value_coef >= 0 and self.velocity_coef >= 0):
            raise ValueError("value_coef and velocity_coef must be >= 0")
        if not 0.0 <= self.weight_average < 1.0:
            raise ValueError(f"weight_average must be in [0, 1), got {self.weight_average}")


STUDENT_ALONE = DaggerConfig(beta_initial=0.0, beta_final=0.0, beta_decay_transitions=0)
"""The student acts every episode, the teacher only labels: the deployed situation, which
the diagnosis scripts measure students in."""


@dataclass(frozen=True)
class AlgoConfig:
    """What a run learns by: the flags `hamnet trainer` and its `hamnet rollout` workers
    share (`--algo`, `--teacher`, `--dagger.*`; workers must be given the trainer's)."""

    algo: Literal["ppo", "dagger"] = "ppo"
    """ppo: learn by PPO. dagger: distil `--teacher` into the run's `--architecture` (default
    `student` then) by DAgger; rollout workers host the teacher beside the student."""
    teacher: Path | None = None
    """With --algo dagger: the teacher, a policy checkpoint `hamnet trainer` wrote (its
    `checkpoints/latest.safetensors`), the same file for the trainer and its workers. Give
    the run the teacher's --stage and encoder flags."""
    dagger: DaggerConfig = field(default_factory=DaggerConfig)
    """DAgger's beta schedule and student update (`--dagger.*`), with --algo dagger: workers
    draw who acts from the same schedule."""
