"""`hamnet trainer`: PPO on rollouts streamed by rollout workers over Zenoh, or with
`--inprocess` on in-process cores (sim, perception, policy and the safety filter's training
profile in this one process, no Zenoh unless `--publish`).

    hamnet trainer --inprocess --max-wall-clock-s 3600          # an hour on the easy stage, one process
    hamnet trainer --workers 2 & hamnet rollout --worker 0 & hamnet rollout --worker 1
    hamnet up compose/train-easy.yaml                           # the same, from a stack file
    hamnet trainer --inprocess --architecture state-mlp          # the plain state-based baseline
    hamnet trainer --stage full --sim.task.timeout 200          # any sim field, on top of a stage
    hamnet trainer --inprocess --resume runs/train              # continue a run from its snapshot
    hamnet trainer --workers 4 --ranks 2                        # two learner processes (or torchrun)

The policy reads UniCORN tokens of the pre-trained encoder shipped in the package, frozen
(the paper's); `--encoder-checkpoint PATH` names another, `--random-encoder` freezes a random
one instead (the ablation). Rollout workers take the same `--stage`, `--sim.*`,
`--architecture`, `--steps-per-rollout` and encoder flags (their `--sim.num-envs` environments each; the trainer learns
from `--workers` of them side by side). The trainer announces its weights before every
rollout (`trainer/weights`, with the schedule counter), publishes the counter and every
iteration's metrics (`trainer/schedule`, `trainer/metrics`; watch with `hamnet monitor`),
writes `<run-dir>/metrics.jsonl` (one line per iteration: returns per reward term, success
rate, episode length, KL, clip fraction, learning rate, env steps/s, policy lag),
`<run-dir>/checkpoints/latest.safetensors` (serve it with `hamnet policy --checkpoint`) and,
at the end, `<run-dir>/summary.json` (success rate of the final policy's mean on
`--eval-episodes` held-out episodes, the curve, command, seed and commit), and prints a
progress line every `--log-period-s`. `hamnet trainer plot RUN_DIR` draws a run's learning
curves as PNG.

    hamnet trainer --algo dagger --inprocess --teacher runs/train-easy/checkpoints/latest.safetensors
    hamnet trainer --algo dagger --teacher CKPT --workers 1 & hamnet rollout --algo dagger --teacher CKPT --worker 0

distils a PPO teacher into the recurrent student on deployable inputs by DAgger (issue 15,
docs/trainer.md "DAgger"), in-process or from rollout workers that host the teacher: the
same checkpoints, `--resume`, metrics, progress line and summary (with the teacher's and the
student's held-out success rates), `--dagger.*` flags.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.runs import commit
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.sim.stages import stage_in
from hamnet.trainer.algorithms.algorithm import Algorithm
from hamnet.trainer.algorithms.choice import algorithm_of
from hamnet.trainer.algorithms.ppo_learner import PPO
from hamnet.trainer.algorithms.teacher import DaggerError
from hamnet.trainer.collection.streamed import Streamed
from hamnet.trainer.config import AlgoConfig
from hamnet.trainer.publisher import TrainerPublisher
from hamnet.trainer.results.summary import write_summary
from hamnet.trainer.runners.launch_ranks import start_other_ranks, wait_for
from hamnet.trainer.runners.ranks import ONE, Ranks, from_environment
from hamnet.trainer.runners.run_config import RunConfig, stage_sim
from hamnet.trainer.runners.runner import Runner
from hamnet.trainer.runners.snapshots import ResumeError
from hamnet.trainer.runners.stopping import until_signalled

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainerConfig:
    """One training run."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    run: Annotated[RunConfig, tyro.conf.arg(name="")] = field(default_factory=RunConfig)
    """The run (`--stage`, `--architecture`, ...; the environments under `--sim.*`, PPO under
    `--ppo.*`)."""
    inprocess: bool = False
    """Collect in this process (`hamnet.trainer.collection.rollout_worker`) instead of from rollout workers."""
    max_policy_lag: int = 0
    """Learn from chunks acted up to this many versions ago (rollout workers must say the
    same); 0: synchronous, on-policy."""
    worker_timeout_s: float = math.inf
    """A rollout worker that sends nothing for this long after an iteration begins drops out
    of it, as one whose liveliness token goes away does at once (a hung worker keeps its
    token); inf: only the token counts. With one learner rank."""
    publish: bool = False
    """With --inprocess: publish the weights, the schedule counter and every iteration's
    metrics on Zenoh (`--namespace`), to watch with `hamnet monitor --namespace NS` and serve
    the newest weights with `hamnet policy`. Streaming runs always publish."""
    weights_period_s: float = 10.0
    """With --inprocess --publish: seconds between two weight announcements (and one at the end)."""
    algorithm: Annotated[AlgoConfig, tyro.conf.arg(name="")] = field(default_factory=AlgoConfig)
    """PPO or DAgger (`--algo`, `--teacher`, `--dagger.*`)."""
    ranks: int = 1
    """Learner processes on this machine (torch.distributed, gloo on loopback): this one is
    rank 0 and starts the others; rank r learns from the rollout workers whose id modulo
    `ranks` is r, and only rank 0 announces weights, publishes, logs and checkpoints.
    `--workers` must be a multiple. Under torchrun (`WORLD_SIZE` set) leave it at 1."""
    resume: Path | None = None
    """Continue the run in this folder from its latest snapshot (`checkpoints/`), appending to
    its metrics.jsonl (it replaces --run-dir). Its architecture, --sim.* and
    --steps-per-rollout must be the snapshot's; budgets count the earlier iterations too."""

    def __post_init__(self) -> None:
        if self.ranks < 1:
            raise ConfigError(f"--ranks must be >= 1, got {self.ranks}")
        if self.ranks > 1 and (self.inprocess or self.algorithm.algo != "ppo"):
            raise ConfigError("--ranks shards rollout workers: it needs PPO without --inprocess")
        if self.run.workers % self.ranks:
            raise ConfigError(
                f"--workers {self.run.workers} must be a multiple of --ranks {self.ranks}"
            )
        if not self.worker_timeout_s > 0:
            raise ConfigError(f"--worker-timeout-s must be > 0, got {self.worker_timeout_s}")

    @property
    def resumed_run(self) -> RunConfig:
        """The run, in the folder it resumes when `resume` is set."""
        if self.resume is None:
            return self.run
        return dataclasses.replace(self.run, run_dir=self.resume)


CONFIG = TrainerConfig
"""The config `hamnet trainer` parses."""


def stage_default(argv: Sequence[str]) -> RunConfig:
    """The run on the stage `--stage` names in `argv` (easy when absent), so every `--sim.*`
    flag changes that stage's value; with `--algo dagger` the student learns."""
    stage = stage_in(argv, "easy")
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--algo", default="ppo")
    student = parser.parse_known_args(list(argv))[0].algo == "dagger"
    return RunConfig(
        stage=stage, sim=stage_sim(stage), architecture="student" if student else "hamnet"
    )


def default_config(argv: Sequence[str]) -> TrainerConfig:
    """The defaults `argv` is parsed on (`stage_default`); `hamnet up --check` uses them too."""
    return TrainerConfig(run=stage_default(argv))


def main(argv: Sequence[str]) -> int:
    """Run `hamnet trainer` (or `hamnet trainer plot`) with arguments `argv`; returns the exit status."""
    if argv and argv[0] == "plot":
        from hamnet.trainer.results.plot import main as plot_main  # matplotlib only when plotting

        return plot_main(argv[1:])
    default = default_config(argv)
    config, identity = parse_service(TrainerConfig, argv, "trainer", __doc__, default=default)
    code = commit()  # the commit of the code that trains
    spawn = config.ranks > 1 and "WORLD_SIZE" not in os.environ  # else torchrun's, or one
    children = start_other_ranks(argv, config.ranks) if spawn else []
    try:
        status = learn(config, identity, code, from_environment())
    finally:
        failed = wait_for(children)
    return status or failed


def learn(config: TrainerConfig, identity: ServiceIdentity, code: str, ranks: Ranks) -> int:
    """Train as this learner rank; the main one then evaluates and writes the summary. Every
    unusable input (a snapshot of another run, DAgger without a usable teacher or with a
    non-student architecture) is one line on stderr and exit status 2."""
    run = config.resumed_run
    if config.run.workers % ranks.size or (ranks.size > 1 and config.inprocess):
        print(
            f"hamnet trainer: {ranks.size} learner ranks need --workers a multiple of them "
            "and no --inprocess",
            file=sys.stderr,
        )
        return 2
    if not ranks.main:  # its own identity on the network
        identity = ServiceIdentity(identity.service, f"{identity.worker}-rank{ranks.rank}")
    try:
        algorithm = algorithm_of(config.algorithm, run)
        if config.inprocess and not config.publish:
            with until_signalled() as running:
                runner = Runner(run, resume=config.resume is not None, algorithm=algorithm)
                runner.run(running=running)
                stopped = not running()
        else:
            with Service(identity, config.common.transport) as service:
                runner = train_with(service, config, algorithm, ranks)
                stopped = not service.running
    except (DaggerError, ResumeError) as error:
        print(f"hamnet trainer: {error}", file=sys.stderr)
        return 2
    if not ranks.main:
        return 0
    held_out, extra = None, {**algorithm.summary_fields(), "stopped_by_signal": stopped}
    if stopped:  # the launcher's grace period leaves no time for the evaluation
        log.info(
            "stopped: checkpoint, metrics and summary written without the held-out "
            "evaluation; `hamnet trainer --resume %s --max-wall-clock-s 0` (the run's other "
            "flags unchanged) evaluates it",
            run.run_dir,
        )
    elif run.eval_episodes:
        held_out, figures = algorithm.held_out(runner.policy, runner.config, runner.env_transitions)
        extra |= figures
        log.info(
            "on %d held-out episodes: success rate %.3f, goal return %.4f",
            run.eval_episodes,
            held_out.success_rate,
            held_out.goal_return,
        )
    print(write_summary(runner.config, held_out, code, runner.commands, extra))
    return 0


def train_with(
    service: Service, config: TrainerConfig, algorithm: Algorithm | None = None, ranks: Ranks = ONE
) -> Runner:
    """Train by `algorithm` (default PPO) while publishing on `service` (the main rank):
    in-process, or from the chunks of this rank's rollout workers."""
    run, resume = config.resumed_run, config.resume is not None
    if config.inprocess:
        runner = Runner(run, resume=resume, algorithm=algorithm)
        return publish_while(service, runner, config.weights_period_s)
    chosen = PPO(run) if algorithm is None else algorithm
    runner = Runner(
        run,
        lambda policy: Streamed(
            service,
            policy,
            config.run.workers,
            run.num_envs,
            config.max_policy_lag,
            ranks=ranks,
            worker_timeout_s=config.worker_timeout_s,
            decoder=chosen.decoder,
            topic=chosen.topic,
        ),
        resume,
        ranks,
        chosen,
    )
    if not ranks.main:
        runner.run(running=lambda: service.running)
        return runner
    return publish_while(service, runner, math.inf)  # the source announces every version


def publish_while(service: Service, runner: Runner, weights_period_s: float) -> Runner:
    """Run `runner` while `service` runs, publishing its weights (every `weights_period_s`
    and at the end), counter and metrics."""
    publisher = TrainerPublisher(service, weights_period_s, runner.config.rollout_steps)
    runner.run(lambda row: publisher.publish(runner.policy, row), lambda: service.running)
    if runner.last_row:
        publisher.publish(runner.policy, runner.last_row, final=True)
    return runner
