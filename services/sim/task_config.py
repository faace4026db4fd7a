"""The task of the MDP (paper, "MDP Design", lines 235-246; Table tab:reward-params): reward
coefficients, success thresholds, workspace bounds and timeout.

`rewards.py` and `termination.py` read one frozen `TaskConfig`. The success thresholds
default to the authors' training configuration (0.05 m, 0.1 rad: what their reported success
rates use), the paper's text (0.1 m) is `TASK_PRESETS["paper"]`. Other defaults are the paper's;
`TASK_PRESETS["code"]` holds the choices of the authors' released code where it differs
(success radius, shaping discount, how corner potentials and the hand distance are taken).
Lengths are metres, angles radians, times policy steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

HandObjectDistance = Literal["bbox", "centre"]
"""How d_{h,o} is measured: to the nearest point of the object's bounding box, or to its
centre (the authors' code)."""


@dataclass(frozen=True)
class TaskConfig:
    """Rewards r = r_s + lambda_r r_r + lambda_c r_c, success, dropping and timeout."""

    success_reward: float = 1.0
    """Value of r_s on the step the object reaches the goal; the paper's r_s = 1_suc
    (line 245), weighted by 1 in r (line 244)."""
    lambda_r: float = 0.15
    """lambda_r: weight of the goal-reaching reward r_r (Table tab:reward-params)."""
    lambda_c: float = 0.03
    """lambda_c: weight of the contact-inducing reward r_c (Table tab:reward-params)."""
    c_g: float = 3.0
    """c_g: scale of the object-goal distance in phi_r = -log(c_g d_og + 1), 1/m."""
    c_r: float = 3.0
    """c_r: scale of the hand-object distance in phi_c = -log(c_r d_ho + 1), 1/m."""
    shaping_gamma: float = 0.99
    """gamma of the shaping terms gamma phi(s') - phi(s): the paper uses the PPO discount
    (0.99, Table tab:PPO); the authors' code uses 1.0."""
    average_corner_potentials: bool = False
    """False: phi_r = -log(c_g d_og + 1) with d_og the mean distance of the 8 bounding-box
    corners (paper); True: phi_r is the mean over corners of -log(c_g d_i + 1) (code)."""
    hand_object_distance: HandObjectDistance = "bbox"
    """d_ho from the end-effector tip to the nearest point of the object's bounding box (0
    inside it), or to the object's centre ("centre", the authors' code)."""
    success_radius: float = 0.05
    """Largest object-goal position error that counts as success, m: the authors' training
    configuration (rss_train.yaml:122 task.goal_radius), which produced the reported success
    rates; the paper's text says 0.1 (preset "paper")."""
    success_angle: float = 0.1
    """Largest object-goal orientation error that counts as success, rad (rss_train.yaml:123
    task.goal_angle)."""
    workspace_margin_xy: float = 0.3
    """The object is dropped once its centre leaves the table's xy extent grown by this, m
    (the authors' code)."""
    drop_depth: float = 0.1
    """The object is dropped once its centre is this far below the table top, m."""
    workspace_height: float = 0.5
    """The object leaves the workspace once its centre is this far above the table top, m
    (the authors' code); inf disables the bound."""
    timeout: int = 300
    """Policy steps after which an episode is truncated (not terminated)."""

    def __post_init__(self) -> None:
        for name in ("success_reward", "lambda_r", "lambda_c"):
            if not math.isfinite(getattr(self, name)) or getattr(self, name) < 0:
                raise ValueError(f"{name} must be finite and >= 0, got {getattr(self, name)}")
        for name in ("c_g", "c_r", "success_radius", "success_angle"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0.0 < self.shaping_gamma <= 1.0:
            raise ValueError(f"shaping_gamma must be in (0, 1], got {self.shaping_gamma}")
        if self.hand_object_distance not in ("bbox", "centre"):
            choice = self.hand_object_distance
            raise ValueError(f"hand_object_distance must be 'bbox' or 'centre', got {choice!r}")
        for name in ("workspace_margin_xy", "drop_depth", "workspace_height"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.timeout < 1:
            raise ValueError(f"timeout must be >= 1 policy step, got {self.timeout}")


TASK_PRESETS: dict[str, TaskConfig] = {
    "paper": TaskConfig(success_radius=0.1),
    "code": TaskConfig(
        success_radius=0.05,
        shaping_gamma=1.0,
        average_corner_potentials=True,
        hand_object_distance="centre",
    ),
}
"""Named task variants: the paper's MDP, and the authors' released code where it differs."""
