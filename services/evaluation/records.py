"""One record per evaluated episode, the failure reason it ended with, and its JSON form.

The runner that plays `hamnet eval`'s episodes builds an `EpisodeRecord` per episode; the
metrics, report and figure read only these. Records travel as dicts (`to_dict`,
`from_dict`) and as JSON lines, one episode a line (`write_records`, `read_records`), so a
finished evaluation can be reported or compared again without playing it.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hamnet.sim.domains import DOMAIN_NAMES

PROCEDURAL = "procedural"
"""The suite of held-out procedurally generated scenes (paper Sec. proc-gen)."""

BENCHMARK_DOMAINS = DOMAIN_NAMES
"""The nine digital twins of the simulated benchmark (paper Sec. sec:benchmark; the same nine
domains as its real-world table tab:real-result), in issue 31's order."""

SUITES = (PROCEDURAL, *BENCHMARK_DOMAINS)
"""Every suite an episode may belong to, in the order reports list them."""

FAILURE_REASONS = ("timeout", "drop", "safety_stop", "collision", "torque_limit")
"""Why an episode failed; `failure_reason` picks one per episode."""

SUCCESS = "success"
"""The reason of an episode that reached its goal."""


def failure_reason(
    success: bool, dropped: bool, safety_stop: bool, collision: bool, torque_limit: bool
) -> str:
    """The one reason an episode ended with: "success" or one of `FAILURE_REASONS`.

    Precedence: success > drop > safety_stop > collision > torque_limit > timeout. The cause
    that ended the episode, or the most severe one, names the failure, so each episode counts
    once. Success wins as in the sim's own termination (`hamnet.sim.termination.Reason`:
    reaching the goal ends the episode whatever happened on the way). A drop is a terminal
    state of the task (the object left the workspace; nothing can recover it) and a safety
    stop halts the robot, so either one ends the episode. A collision or a torque-limit hit
    usually precedes them and is their symptom; the collision is the more severe (it touches
    the scene, a torque-limit hit is the robot "exceeding the hardware's safety limits",
    paper App. sec:failure-mode). Timeout is what is left: the policy ran out of steps with
    nothing else going wrong (the paper's deadlock, or being stuck against the scene).

    Args:
        success: the object reached the goal within both thresholds.
        dropped: the object left the workspace.
        safety_stop: the safety filter stopped the robot.
        collision: the robot collided (with the scene or itself) during the episode.
        torque_limit: a joint torque limit was exceeded during the episode.
    Returns:
        "success", "drop", "safety_stop", "collision", "torque_limit" or "timeout".
    """
    if success:
        return SUCCESS
    for happened, reason in (
        (dropped, "drop"),
        (safety_stop, "safety_stop"),
        (collision, "collision"),
        (torque_limit, "torque_limit"),
    ):
        if happened:
            return reason
    return "timeout"


@dataclass(frozen=True)
class EpisodeRecord:
    """What one evaluated episode leaves for the report (Python scalars, JSON-able)."""

    suite: str
    """`PROCEDURAL` or one of `BENCHMARK_DOMAINS`."""
    object_name: str
    """The object manipulated."""
    pair: int
    """Index of the start/goal pose pair of this domain-object pair (5 per pair, paper Sec.
    sec:benchmark)."""
    init: int
    """Index of the robot initialisation (128 per pair, paper Sec. sec:benchmark)."""
    success: bool
    """The object reached the goal."""
    reason: str
    """`SUCCESS` or one of `FAILURE_REASONS` (`failure_reason`)."""
    length: int
    """Policy steps the episode lasted."""
    start_distance: float
    """Object-to-goal distance at the start, m."""
    final_distance: float
    """Object-to-goal distance at the end, m."""
    final_angle: float
    """Object-to-goal rotation angle at the end, rad."""

    def __post_init__(self) -> None:
        if self.suite not in SUITES:
            raise ValueError(f"unknown suite {self.suite!r}; known: {', '.join(SUITES)}")
        if self.reason not in (SUCCESS, *FAILURE_REASONS):
            raise ValueError(f"unknown reason {self.reason!r}")
        if self.success != (self.reason == SUCCESS):
            raise ValueError(f"success={self.success} contradicts reason {self.reason!r}")
        if min(self.pair, self.init, self.length) < 0:
            raise ValueError("pair, init and length must be >= 0")

    def to_dict(self) -> dict[str, Any]:
        """The record as a JSON-able dict, one key per field."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EpisodeRecord:
        """The record `to_dict` wrote; an unknown or missing key raises TypeError."""
        return cls(**data)


def write_records(path: Path, records: Iterable[EpisodeRecord]) -> Path:
    """Write `records` to `path` as JSON lines (one episode a line); returns `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(record.to_dict()) + "\n" for record in records))
    return path


def read_records(path: Path) -> list[EpisodeRecord]:
    """The records `write_records` wrote to `path`, in order."""
    lines = path.read_text().splitlines()
    return [EpisodeRecord.from_dict(json.loads(line)) for line in lines if line.strip()]
