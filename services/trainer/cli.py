"""`hamnet train`: PPO in one process, with no Zenoh: the sim, perception, policy and the
safety filter's training profile as in-process cores (`hamnet.trainer.rollout`), the update
and the schedule counter (`hamnet.trainer.runner`).

    hamnet train --stage easy --max-wall-clock-s 3600      # an hour on the easy stage
    hamnet train --architecture mlp --num-envs 32          # a baseline, fewer environments

It writes `<run-dir>/metrics.jsonl` (one line per iteration: returns per reward term, success
rate, episode length, KL, clip fraction, learning rate, env steps/s),
`<run-dir>/checkpoints/latest.safetensors` (serve it with `hamnet policy --checkpoint`) and,
at the end, `<run-dir>/summary.json` (success rate of the final policy's mean on
`--eval-episodes` held-out episodes, the curve, command, seed and commit),
and prints a progress line every `--log-period-s`. `hamnet train plot RUN_DIR` draws a run's
learning curves as PNG. Training from streamed rollouts (rollout workers and the service chain
over Zenoh) is the trainer service, not built yet.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

from hamnet.runtime.cli import Flattened, LogConfig, parse
from hamnet.runtime.logs import configure_logging
from hamnet.trainer.evaluate import success_rate
from hamnet.trainer.runner import RunConfig, Runner
from hamnet.trainer.summary import write_summary

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    """One in-process training run."""

    run: Annotated[RunConfig, Flattened] = field(default_factory=RunConfig)
    logging: Annotated[LogConfig, Flattened] = field(default_factory=LogConfig)


CONFIG = TrainConfig
"""The config `hamnet train` parses."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet train` (or `hamnet train plot`) with arguments `argv`; returns the exit status."""
    if argv and argv[0] == "plot":
        from hamnet.trainer.plot import main as plot_main  # matplotlib only when plotting

        return plot_main(argv[1:])
    config = parse(CONFIG, argv, "hamnet train", __doc__)
    configure_logging("train", config.logging.log_level, config.logging.log_format)
    runner = Runner(config.run)
    runner.run()
    rate = None
    if config.run.eval_episodes:
        rate = success_rate(runner.policy, config.run, config.run.eval_episodes, runner.env_transitions)
        log.info("final success rate on %d held-out episodes: %.3f", config.run.eval_episodes, rate)
    print(write_summary(config.run, rate))
    return 0
