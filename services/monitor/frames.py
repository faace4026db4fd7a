"""What the view draws, one small frozen dataclass per topic: the environment in focus cut
out of each batched message (the shell's decoders build them; the view never sees
protobuf). Every frame carries `step` (the producer's `header.step`) and `stamp_ns` (wall
clock of production, ns since the epoch), the view's two timelines."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StateFrame:
    """sim/<w>/state of the environment in focus."""

    step: int
    stamp_ns: int
    episode_id: int
    q: np.ndarray
    """(J,) joint positions, rad."""
    goal_pose: np.ndarray
    """(7,) goal of the object: position (m) and quaternion wxyz."""
    object_pose: np.ndarray | None
    """(7,) object pose, position (m) and quaternion wxyz; None from a real robot (no
    privileged block)."""


@dataclass(frozen=True)
class SceneFrame:
    """sim/<w>/scene of the environment in focus (an episode starts)."""

    step: int
    stamp_ns: int
    episode_id: int
    centre: np.ndarray
    """(C, 3) cuboid centres, m."""
    quat: np.ndarray
    """(C, 4) cuboid orientations, wxyz."""
    half_extent: np.ndarray
    """(C, 3) cuboid half extents, m."""
    active: np.ndarray
    """(C,) bool: the cuboid is part of the scene."""
    object_id: str
    """Library name of the object."""
    object_points: np.ndarray
    """(P, 3) surface points of the object in its own frame, m."""
    start_pose: np.ndarray
    """(7,) start pose of the object, position (m) and wxyz."""
    goal_pose: np.ndarray
    """(7,) goal pose of the object, position (m) and wxyz."""


@dataclass(frozen=True)
class CloudsFrame:
    """The three clouds of perception/<w>/tokens for the environment in focus (world, m)."""

    step: int
    stamp_ns: int
    object: np.ndarray
    """(P, 3) object cloud."""
    environment: np.ndarray
    """(P, 3) environment cloud."""
    local: np.ndarray
    """(P, 3) local (focal) cloud."""


@dataclass(frozen=True)
class ActionFrame:
    """policy/<w>/action for the environment in focus."""

    step: int
    stamp_ns: int
    policy_version: int
    module_weights: np.ndarray | None
    """(L, M) per base-network layer, the softmax over modules; None for a baseline policy."""
    values: np.ndarray | None
    """(R,) value estimate per reward term; None when not sent."""


@dataclass(frozen=True)
class TransitionFrame:
    """sim/<w>/transition: the focus environment's reward terms, and every environment's
    episode ends (the success rate counts the whole worker)."""

    step: int
    stamp_ns: int
    drawn: bool
    """Whether this step is drawn (reward terms); episode ends are always counted."""
    reward_names: tuple[str, ...]
    reward_terms: np.ndarray
    """(R,) reward terms of the environment in focus."""
    done: np.ndarray
    """(B,) bool: the episode ended (terminated or truncated) in this step."""
    success: np.ndarray
    """(B,) bool: the episode ended in success."""


@dataclass(frozen=True)
class StageFigures:
    """One StageStats: what a safety stage did since the previous report."""

    stage: str
    commands: int
    clipped: int
    mean_excess: float
    max_excess: float


@dataclass(frozen=True)
class EventFrame:
    """safety/<w>/event."""

    step: int
    stamp_ns: int
    kind: str
    """SafetyEventKind name; SAFETY_EVENT_KIND_UNSPECIFIED is a periodic statistics report."""
    stage: str
    reason: str
    env_ids: np.ndarray
    """(K,) environments concerned."""
    stages: tuple[StageFigures, ...]

    @property
    def is_statistics(self) -> bool:
        """A periodic per-stage report rather than something that happened."""
        return self.kind == "SAFETY_EVENT_KIND_UNSPECIFIED"


@dataclass(frozen=True)
class MetricsFrame:
    """trainer/metrics: scalar statistics of one update."""

    step: int
    stamp_ns: int
    iteration: int
    scalars: dict[str, float]
