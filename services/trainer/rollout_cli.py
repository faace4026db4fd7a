"""`hamnet rollout`: a rollout worker. It hosts the in-process cores (sim, perception, the
policy's input builder, the safety filter's training profile) for `--sim.num-envs`
environments, acts with the newest weights `hamnet trainer` announces and streams every
rollout back as a RolloutChunk (`hamnet.trainer.collection.worker_service`).

    hamnet trainer --workers 2 & hamnet rollout --worker 0 & hamnet rollout --worker 1
    hamnet up compose/train-easy.yaml                  # trainer and workers from a stack file

Give it the trainer's `--stage`, `--sim.*`, `--architecture`, `--steps-per-rollout`, encoder
flags (`--encoder-checkpoint`, `--random-encoder`) and `--max-policy-lag` (the other run
flags are the trainer's and are ignored here). `--worker K` (a number) names the worker and seeds its environments apart.

    hamnet trainer --algo dagger --teacher CKPT --workers 1 & hamnet rollout --algo dagger --teacher CKPT --worker 0

makes DAgger's worker (docs/trainer.md "DAgger"): the teacher from CKPT labels, the student
acts with the trainer's weights, who acts is drawn from beta at the announced counter; give it
the trainer's `--teacher` (the same file: the trainer refuses another's chunks) and
`--dagger.*`. A missing or unusable teacher, or a non-student `--architecture`, is one line
on stderr and exit status 2.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

import torch
import tyro

from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service
from hamnet.trainer.algorithms.choice import algorithm_of
from hamnet.trainer.algorithms.teacher import DaggerError
from hamnet.trainer.cli import stage_default
from hamnet.trainer.collection.worker_service import RolloutService
from hamnet.trainer.config import AlgoConfig
from hamnet.trainer.runners.run_config import RunConfig


@dataclass(frozen=True)
class RolloutConfig:
    """One rollout worker."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    run: Annotated[RunConfig, tyro.conf.arg(name="")] = field(default_factory=RunConfig)
    """The trainer's run flags: this worker reads the stage, `--sim.*`, the architecture,
    the steps per rollout and the encoder checkpoint."""
    max_policy_lag: int = 0
    """0: wait for new weights after every rollout (on-policy); L > 0: keep acting with the
    newest weights held (the trainer learns from chunks up to L versions old)."""
    algorithm: Annotated[AlgoConfig, tyro.conf.arg(name="")] = field(default_factory=AlgoConfig)
    """The trainer's `--algo`, `--teacher` and `--dagger.*`: with dagger this worker hosts
    the teacher and streams demonstrations."""


CONFIG = RolloutConfig
"""The config `hamnet rollout` parses."""


def default_config(argv: Sequence[str]) -> RolloutConfig:
    """The defaults `argv` is parsed on (`stage_default`); `hamnet up --check` uses them too."""
    return RolloutConfig(run=stage_default(argv))


def main(argv: Sequence[str]) -> int:
    """Run `hamnet rollout` with arguments `argv`; returns the exit status."""
    default = default_config(argv)
    config, identity = parse_service(RolloutConfig, argv, "rollout", __doc__, default=default)
    torch.set_num_threads(1)
    try:
        algorithm = algorithm_of(config.algorithm, config.run)
        algorithm.prepare(config.run)  # a non-student architecture, before the session opens
    except DaggerError as error:
        print(f"hamnet rollout: {error}", file=sys.stderr)
        return 2
    with Service(identity, config.common.transport) as service:
        RolloutService(service, config.run, config.max_policy_lag, algorithm=algorithm).run()
    return 0
