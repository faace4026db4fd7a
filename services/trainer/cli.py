"""`hamnet train`: PPO in one process, with no Zenoh: the sim, perception, policy and the
safety filter's training profile as in-process cores (`hamnet.trainer.rollout`), the update
and the schedule counter (`hamnet.trainer.runner`).

    hamnet train --stage easy --max-wall-clock-s 3600      # an hour on the easy stage
    hamnet train --architecture state-mlp                  # the plain state-based baseline
    hamnet train --stage full --sim.task.timeout 200       # any sim field, on top of a stage
    hamnet train --sim.num-envs 32 --sim.seed 3            # environments and seed

It writes `<run-dir>/metrics.jsonl` (one line per iteration: returns per reward term, success
rate, episode length, KL, clip fraction, learning rate, env steps/s),
`<run-dir>/checkpoints/latest.safetensors` (serve it with `hamnet policy --checkpoint`) and,
at the end, `<run-dir>/summary.json` (success rate of the final policy's mean on
`--eval-episodes` held-out episodes, the curve, command, seed and commit),
and prints a progress line every `--log-period-s`. `hamnet train plot RUN_DIR` draws a run's
learning curves as PNG. With `--publish` the run also announces its weights, the schedule
counter and its metrics on Zenoh (`hamnet.trainer.shell`). Training from streamed rollouts (rollout workers and the service chain
over Zenoh) is the trainer service, not built yet.
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

import tyro

from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service
from hamnet.sim.stages import STAGES
from hamnet.trainer.evaluate import success_rate
from hamnet.trainer.runner import RunConfig, Runner, stage_sim
from hamnet.trainer.shell import TrainerPublisher
from hamnet.trainer.summary import write_summary

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    """One in-process training run."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    run: Annotated[RunConfig, tyro.conf.arg(name="")] = field(default_factory=RunConfig)
    """The run (`--stage`, `--architecture`, ...; the environments under `--sim.*`, PPO under
    `--ppo.*`)."""
    publish: bool = False
    """Publish the weights, the schedule counter and every iteration's metrics on Zenoh
    (`--namespace`): watch with `hamnet monitor --namespace NS`, serve the newest weights
    with `hamnet policy`."""
    weights_period_s: float = 10.0
    """With --publish: seconds between two weight announcements (and one at the end)."""


CONFIG = TrainConfig
"""The config `hamnet train` parses."""


def stage_default(argv: Sequence[str]) -> TrainConfig:
    """The defaults of a run on the stage `--stage` names in `argv` (easy when absent), so
    every `--sim.*` flag changes that stage's value."""
    known, _ = _STAGE_FLAG.parse_known_args(list(argv))
    stage = known.stage if known.stage in STAGES else "easy"  # tyro reports a bad name
    return TrainConfig(run=RunConfig(stage=stage, sim=stage_sim(stage)))


_STAGE_FLAG = argparse.ArgumentParser(add_help=False)
_STAGE_FLAG.add_argument("--stage", default="easy")


def main(argv: Sequence[str]) -> int:
    """Run `hamnet train` (or `hamnet train plot`) with arguments `argv`; returns the exit status."""
    if argv and argv[0] == "plot":
        from hamnet.trainer.plot import main as plot_main  # matplotlib only when plotting

        return plot_main(argv[1:])
    config, identity = parse_service(CONFIG, argv, "train", __doc__, default=stage_default(argv))
    runner = Runner(config.run)
    if config.publish:
        with Service(identity, config.common.transport) as service:
            publisher = TrainerPublisher(service, config.weights_period_s)
            runner.run(lambda row: publisher.publish(runner.policy, row), lambda: service.running)
            if runner.last_row:
                publisher.publish(runner.policy, runner.last_row, final=True)
    else:
        runner.run()
    rate = None
    if config.run.eval_episodes:
        rate = success_rate(runner.policy, config.run, config.run.eval_episodes, runner.env_transitions)
        log.info("final success rate on %d held-out episodes: %.3f", config.run.eval_episodes, rate)
    print(write_summary(config.run, rate))
    return 0
