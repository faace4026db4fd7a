"""`hamnet bridge`: the real FR3 in place of the sim, behind the same topics (see
`hamnet.bridge.shell` for the topics and the pacing).

`--driver fake` runs the strict simulated FR3 (`hamnet.bridge.fake`), for tests; `franky`
(libfranka through franky) is not built yet. `hamnet bridge check` connects, reads the
limits and the state, measures the round trip and prints a verdict (`hamnet.bridge.check`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Literal

from hamnet.bridge.core import BridgeCore
from hamnet.bridge.driver import Driver
from hamnet.bridge.fake import FakeDriver, FakeDriverConfig
from hamnet.bridge.shell import BridgeShell, LoopConfig
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.service import Service

DriverName = Literal["franky", "fake"]


@dataclass(frozen=True)
class BridgeServiceConfig:
    """One robot: its driver, the pace of its states and its reports."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    driver: DriverName = "franky"
    """franky (a real FR3 through libfranka; not built yet) or fake (the strict simulated
    FR3, for tests)."""
    fake: FakeDriverConfig = field(default_factory=FakeDriverConfig)
    """The fake driver's options."""
    loop: Annotated[LoopConfig, Flattened] = field(default_factory=LoopConfig)


def make_driver(name: DriverName, fake: FakeDriverConfig) -> Driver:
    """The driver called `name`; ConfigError for one not built yet."""
    if name == "fake":
        return FakeDriver(fake)
    raise ConfigError(f"the {name} driver is not built yet (issue #17): use --driver fake")


def main(argv: Sequence[str]) -> int:
    """Run `hamnet bridge` (or `hamnet bridge check`) with arguments `argv`."""
    if argv and argv[0] == "check":
        from hamnet.bridge.check import main as check

        return check(argv[1:])
    config, identity = parse_service(CONFIG, argv, "bridge", __doc__)
    core = BridgeCore(make_driver(config.driver, config.fake), config.loop.policy_period_s)
    with Service(identity, config.common.transport) as service:
        return BridgeShell(service, core, config.loop).run()


CONFIG = BridgeServiceConfig
"""The config `hamnet bridge` parses (the launcher validates stack files against it)."""
