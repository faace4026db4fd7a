"""`hamnet policy`: HAMnet (or a baseline) serving batched actions for every robot state and
its perception tokens, with hot-reloaded weights from the trainer (see
`hamnet.policy.shell` for the topics).

Start from a checkpoint (`--checkpoint run/policy.safetensors`, the bytes of a weights
announcement), a policy shipped in the package by name (`--checkpoint easy-teacher`) or, for tests and demos, from random weights (`--random-init hamnet`: version
0, and a warning that the actions are meaningless). `--print-params` prints the parameter
counts of every architecture next to the paper's and exits.

`--rollout-horizon T` makes the service chain a rollout source: the policy also publishes
RolloutChunks of T steps (what it served, joined with the sim's transitions) for
`hamnet trainer --workers 1 --sim.num-envs B --steps-per-rollout T --max-policy-lag L`,
with L > 0 because the chain keeps acting while the trainer learns (docs/trainer.md).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.policy.params import parameter_table
from hamnet.policy.registry import ARCHITECTURES, build
from hamnet.policy.serving import PolicyLoopConfig
from hamnet.policy.shell import PORTS, PolicyShell
from hamnet.policy.shipped import read_weights
from hamnet.policy.weights import WeightsError, policy_from
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PolicyServiceConfig:
    """One policy worker: which weights it starts from and how it infers."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    checkpoint: Annotated[Path | None, tyro.conf.arg(aliases=("--weights",))] = None
    """safetensors checkpoint written by the trainer (architecture, config and version are
    in its metadata), or the name of a policy shipped in the package (easy-teacher: PPO on
    the easy stage; easy-student: distilled from it, deployable inputs; easy-paddle: PPO in
    the paddle-twist action space; easy-paddle-student: distilled from it; easy-guided: PPO
    with the scripted guide in the paddle space; easy-guided-student: distilled from it;
    easy-push: the guided hour with the corrected pusher, the best (0.5); easy-push-student:
    distilled from it, the best student (0.41); see docs/policy.md). Required unless
    --random-init or --print-params."""
    random_init: str | None = None
    """Serve randomly initialised weights of this architecture (version 0), for tests and
    demos only: one of hamnet, hamnet-paper, hamnet-nogate, hamnet-envcode, mlp, hyper, sm,
    student."""
    print_params: bool = False
    """Print the parameter counts of every architecture next to the paper's, then exit."""
    loop: Annotated[PolicyLoopConfig, Flattened] = field(default_factory=PolicyLoopConfig)

    def __post_init__(self) -> None:
        if self.checkpoint is not None and self.random_init is not None:
            raise ValueError("give either --checkpoint or --random-init, not both")
        if self.checkpoint is None and self.random_init is None and not self.print_params:
            raise ValueError(
                "hamnet policy needs --checkpoint PATH (or --random-init ARCH for a demo)"
            )
        if self.random_init is not None and self.random_init not in ARCHITECTURES:
            raise ValueError(
                f"unknown architecture {self.random_init!r}; known: {', '.join(ARCHITECTURES)}"
            )


CONFIG = PolicyServiceConfig
"""The config `hamnet policy` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet policy` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "policy", __doc__, ports=PORTS)
    if config.print_params:
        print(parameter_table())
        return 0
    if config.random_init is not None:
        policy, version = build(config.random_init, seed=config.loop.compute.seed), 0
        log.warning(
            "serving RANDOM %s weights (version 0): actions are meaningless until the "
            "trainer publishes weights",
            config.random_init,
        )
    else:
        try:
            weights = read_weights(config.checkpoint)
            policy, version = policy_from(weights), weights.version
        except WeightsError as error:
            log.error("%s", error)
            return 2
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        return PolicyShell(service, policy, version, config.loop).run()
