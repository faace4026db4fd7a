"""`hamnet bridge` on plain links says at its start that anyone on its network can command
the robot (a secure stack is the way to run a real one)."""

from __future__ import annotations

import subprocess
import sys

from hamnet.bridge.cli import NOT_SECURE
from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args


def test_a_bridge_on_plain_links_warns_that_anyone_can_command_the_robot(
    transport: TransportConfig,
) -> None:
    command = [sys.executable, "-m", "hamnet", "bridge", "--driver", "fake", "--max-steps", "3",
               "--policy-period-s", "0.05", *transport_args(transport)]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert NOT_SECURE in done.stderr
    assert "can command the robot and reset it" in NOT_SECURE
