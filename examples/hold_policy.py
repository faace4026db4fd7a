"""A policy that holds every arm where it stands: the smallest service that closes the loop.
Run it in place of `hamnet policy`: hamnet sim & hamnet safety & python examples/hold_policy.py"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Annotated

import numpy as np

from hamnet.fr3.limits import ACTION_DIM
from hamnet.messages import action, robot_state
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.codec import parse
from hamnet.runtime.loop_report import LoopReport
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import ReportConfig

PORTS = Ports(inputs={"state": "sim/<w>/state"}, outputs={"action": "policy/<w>/action"})


@dataclass(frozen=True)
class HoldConfig:
    """Where it runs, and how often it reports."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)


def decode_state(key: str, payload: bytes) -> robot_state.StateIn:
    return robot_state.decode(parse(RobotState, payload), required=("q", "episode_ids"))


def main(argv: Sequence[str]) -> int:
    config, identity = parse_service(HoldConfig, argv, "hold-policy", __doc__, ports=PORTS)
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        port = service.ports(PORTS)
        service.inbox.subscribe("state", port["state"], decoder=decode_state)
        actions = service.publisher(port["action"])
        report = LoopReport(config.report.report_period_s, lambda w: f"{w.rate('n'):.1f} actions/s")
        while service.running:
            report.tick()
            if (received := service.receive(timeout=0.1)) is None:
                continue
            state = received.value
            # A zero action: no joint residual, the middle of the stiffness and damping ranges.
            hold = SimpleNamespace(action=np.zeros((len(state.q), ACTION_DIM)))
            actions.put(action.encode(state.step, 0, state.episode_ids, hold, True))
            report.count("n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
