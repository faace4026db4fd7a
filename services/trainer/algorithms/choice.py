"""The algorithm `--algo` names, built from the flags `hamnet trainer` and its rollout
workers share."""

from __future__ import annotations

from hamnet.trainer.algorithms.algorithm import Algorithm
from hamnet.trainer.algorithms.dagger_learner import Dagger
from hamnet.trainer.algorithms.ppo_learner import PPO
from hamnet.trainer.algorithms.teacher import DaggerError, load_teacher
from hamnet.trainer.config import AlgoConfig
from hamnet.trainer.runners.run_config import RunConfig


def algorithm_of(config: AlgoConfig, run: RunConfig) -> Algorithm:
    """PPO on `run`'s settings, or DAgger from `config.teacher`.

    Raises:
        DaggerError: DAgger without a usable teacher.
    """
    if config.algo == "ppo":
        return PPO(run)
    if config.teacher is None:
        raise DaggerError(
            "--algo dagger needs --teacher CKPT, a policy checkpoint of "
            "hamnet trainer (RUN_DIR/checkpoints/latest.safetensors)"
        )
    return Dagger(load_teacher(config.teacher), config.dagger)
