"""`hamnet bridge`: the real FR3 in place of the sim, behind the same topics (see
`hamnet.bridge.shell` for the topics and the pacing).

`--driver franky` (the default) drives an FR3 through libfranka (`hamnet.bridge.franky_driver`;
the `franky` extra; `franky-sim` serves the same protocol on loopback: run `franky-sim`, then
`--franky.host` the address it prints and `--franky.realtime ignore`); `--driver fake` runs
the strict simulated FR3 (`hamnet.bridge.fake`), for tests. `hamnet bridge check` connects,
reads the limits and the state, measures the round trip and prints a verdict
(`hamnet.bridge.check`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Literal

from hamnet.bridge.core import BridgeCore
from hamnet.bridge.driver import Driver
from hamnet.bridge.fake import FakeDriver, FakeDriverConfig
from hamnet.bridge.franky_driver import FrankyDriver, FrankyDriverConfig
from hamnet.bridge.loop import BridgeLoopConfig
from hamnet.bridge.shell import PORTS, BridgeShell
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service

DriverName = Literal["franky", "fake"]

NOT_SECURE = (
    "hamnet bridge: WARNING: not secure (no --tls-dir): any process that reaches this Zenoh "
    "network, on this machine or beside it, can command the robot and reset it after an "
    "error. Run it in a secure stack (compose/real.yaml; docs/security.md)."
)
"""What a bridge on plain links says at its start."""


@dataclass(frozen=True)
class DriverConfig:
    """Which robot, and its driver's options (the service and its check extend it)."""

    driver: DriverName = "franky"
    """franky (an FR3, or franky-sim, through libfranka) or fake (the strict simulated FR3,
    for tests)."""
    franky: FrankyDriverConfig = field(default_factory=FrankyDriverConfig)
    """The franky driver's options."""
    fake: FakeDriverConfig = field(default_factory=FakeDriverConfig)
    """The fake driver's options."""


@dataclass(frozen=True)
class BridgeServiceConfig(DriverConfig):
    """One robot: its driver, the pace of its states and its reports."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    loop: Annotated[BridgeLoopConfig, Flattened] = field(default_factory=BridgeLoopConfig)


def make_driver(config: DriverConfig) -> Driver:
    """The chosen driver, not yet connected (ConfigError when its extra is missing)."""
    if config.driver == "fake":
        return FakeDriver(config.fake)
    return FrankyDriver(config.franky)


def main(argv: Sequence[str]) -> int:
    """Run `hamnet bridge` (or `hamnet bridge check`) with arguments `argv`."""
    if argv and argv[0] == "check":
        from hamnet.bridge.check import main as check

        return check(argv[1:])
    if argv and argv[0] == "gap":
        from hamnet.bridge.gap import main as gap

        return gap(argv[1:])
    config, identity = parse_service(CONFIG, argv, "bridge", __doc__, ports=PORTS)
    if config.common.transport.tls_dir is None:
        print(NOT_SECURE, file=sys.stderr)
    try:
        core = BridgeCore(make_driver(config), config.loop.policy_period_s)
    except ConnectionError as error:
        print(f"hamnet bridge: {error} (`hamnet bridge check` says more)", file=sys.stderr)
        return 2
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        return BridgeShell(service, core, config.loop).run()


CONFIG = BridgeServiceConfig
"""The config `hamnet bridge` parses (the launcher validates stack files against it)."""
