"""`hamnet bridge check`: before any policy runs, is the robot there and fit to follow one?

Connects through the chosen driver, reads the limits and the state, then sends `--rounds`
holds of the first measured position through the bridge's own command path (`BridgeCore`: the
same pre-check as in service) and times each send plus the next read. Verdict ok (exit 0)
when the state is finite and inside the limits, no error came back and the slowest round
trip is within `--max-round-trip-fraction` of the policy period; else not ok (exit 1), with
the reasons. No Zenoh: it talks to the robot only.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hamnet.bridge.cli import DriverConfig, make_driver
from hamnet.bridge.core import BridgeCommand, BridgeCore
from hamnet.messages.safe_command import hold_command
from hamnet.runtime.cli import parse
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class CheckConfig(DriverConfig):
    """Which robot to check, and how hard."""

    policy_period_s: float = 0.1
    """The policy period the robot will be commanded at, s."""
    rounds: int = 20
    """Holds sent to measure the round trip."""
    max_round_trip_fraction: float = 0.1
    """The slowest round trip may take at most this share of the policy period."""

    def __post_init__(self) -> None:
        if self.rounds < 1:
            raise ConfigError(f"--rounds must be >= 1, got {self.rounds}")
        if not 0.0 < self.max_round_trip_fraction <= 1.0:
            raise ConfigError("--max-round-trip-fraction must be in (0, 1]")


def check(config: CheckConfig) -> list[str]:
    """Run the check, printing what it finds; returns the reasons it is not ok."""
    try:
        core = BridgeCore(make_driver(config), config.policy_period_s)
    except ConnectionError as error:
        return [f"cannot connect: {error}"]
    problems = []
    try:
        limits, reading = core.limits, core.read()
        print(
            f"connected: control period {1e3 * core.driver.control_period_s:.1f} ms, "
            f"{core.samples} samples per {1e3 * config.policy_period_s:.0f} ms policy period"
        )
        print(
            f"limits: q_min {np.round(limits.q_min, 3).tolist()}, "
            f"q_max {np.round(limits.q_max, 3).tolist()}, tau_max {limits.tau_max.tolist()}"
        )
        if reading is None:
            return ["cannot read the state"]
        print(
            f"state: q {np.round(reading.q, 3).tolist()}, "
            f"ee {np.round(reading.ee_position, 3).tolist()} m"
        )
        finite = all(np.isfinite(v).all() for v in (reading.q, reading.dq, reading.tau))
        if not finite:
            problems.append("the state holds NaN or Inf")
        elif np.any(reading.q < limits.q_min) or np.any(reading.q > limits.q_max):
            problems.append("the joints are outside their limits")
        trips = []
        hold = hold_command(reading.q[None], core.samples)  # where the arm stood at first
        for step in range(config.rounds):
            started = time.perf_counter()
            core.execute(BridgeCommand(step, core.episode_id, hold), step)
            reading = core.read()
            trips.append(time.perf_counter() - started)
            if reading is None or not core.streaming:
                break
        worst = max(trips)
        print(
            f"round trip over {len(trips)} holds: median {1e3 * np.median(trips):.2f} ms, "
            f"max {1e3 * worst:.2f} ms"
        )
        if core.errors:
            problems += [f"robot error {e.name}: {e.reason}" for e in core.errors]
        if worst > config.max_round_trip_fraction * config.policy_period_s:
            problems.append(
                f"round trip {1e3 * worst:.1f} ms is over "
                f"{config.max_round_trip_fraction:.0%} of the policy period"
            )
    finally:
        core.driver.close()
    return problems


def main(argv: Sequence[str]) -> int:
    """Run `hamnet bridge check`; exit 0 when the robot is fit, 1 when not."""
    config = parse(CheckConfig, argv, "hamnet bridge check", __doc__)
    problems = check(config)
    print("verdict: ok" if not problems else f"verdict: NOT OK: {'; '.join(problems)}")
    return 0 if not problems else 1
