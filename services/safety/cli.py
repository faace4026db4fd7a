"""`hamnet safety`: the safety filter between policy and robot over Zenoh, with the watchdog
and the e-stop queryable (see `hamnet.safety.shell` for the topics, `hamnet.safety.supervisor`
for the timing).

`--profile` picks the stage switches for a use (training, finetune, deploy: see
`hamnet.safety.config.with_profile`; deploy, the full chain with Ruckig, by default). Stages
are configured under `--safety.<stage>.<field>` (e.g. `--safety.cartesian-clip.eps-x 0.1`),
the reference under `--trajectory.<field>` (80 Hz samples for the sim,
`--trajectory.control-rate-hz 1000` for libfranka).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service
from hamnet.safety.config import Profile, SafetyConfig, with_profile
from hamnet.safety.references import TrajectoryConfig
from hamnet.safety.shell import PORTS, SafetyShell
from hamnet.safety.supervisor import SafetyLoopConfig


@dataclass(frozen=True)
class SafetyServiceConfig:
    """One safety worker: the filter's stages, its reference, the watchdog and reports."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    profile: Profile = "deploy"
    """training (the paper's MDP: no Cartesian clip, no pre-clip, the target on every sample),
    finetune (training plus the annealed Cartesian clip) or deploy (every stage, Ruckig)."""
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    """Stages 1-5 and 7 of the filter."""
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    """Stage 6: jerk-limited references at the executor's control rate."""
    loop: Annotated[SafetyLoopConfig, Flattened] = field(default_factory=SafetyLoopConfig)


CONFIG = SafetyServiceConfig
"""The config `hamnet safety` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet safety` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "safety", __doc__, ports=PORTS)
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        safety = with_profile(config.profile, config.safety)
        return SafetyShell(service, config.loop, safety, config.trajectory).run()
