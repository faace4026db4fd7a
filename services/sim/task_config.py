"""The task of the MDP (paper, "MDP Design", lines 235-246; Table tab:reward-params): reward
coefficients, success thresholds, workspace bounds and timeout.

`rewards.py` and `termination.py` read one frozen `TaskConfig`. The defaults are the authors'
training configuration where it decides what is learned: success thresholds (0.05 m, 0.1
rad: what their reported success rates use) and the rewards their code computes (shaping
discount 1.0, per-corner log potentials averaged, hand distance to the object's centre).
`TASK_PRESETS["paper"]` is the paper's text (0.1 m, the PPO discount 0.99 in the shaping,
log of the mean corner distance, hand distance to the bounding box); `TASK_PRESETS["code"]`
names the defaults. Lengths are metres, angles radians, times policy steps.

What the authors' rewards are: rss_train.yaml's task.pot_coef 0.16, hand_obj_pot_coef
0.03, rel_pot_rew_scale 0.2, use_log_reward, k_1, k_2, epsilon and gamma are never read by
the task it trains (PushWithArmTask: hand_obj_pot_coef and rel_pot_rew_scale are marked
deprecated at ham/src/ham/env/task/push_with_arm_task.py:79-85; the others are fields of
PushTask.Config, push_task.py:213-247, read by no code). The rewards come from
`rewd_coef` (succ 1.0, reach 0.15, contact 0.15 * 0.2 = 0.03, push_with_arm_task.py:102-108,
applied at 402-413) over `PotLogRew` (k = 3.0, gamma = 1.0, the potential averaged over the
keypoints, ham/src/ham/env/task/rewards.py:91-113): the goal term over the 8 bounding-box
corners (push_task.py:153-161), the contact term from the tip to the object's position
(push_with_arm_task.py:289-292, 349-350). These are the paper's lambda_r, lambda_c, c_g, c_r.
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
    shaping_gamma: float = 1.0
    """gamma of the shaping terms gamma phi(s') - phi(s): 1.0 in the authors' code
    (PotLogRew.gamma, ham/src/ham/env/task/rewards.py:96), so an episode's shaping return is
    phi(s_T) - phi(s_0) exactly; the paper uses the PPO discount (0.99, Table tab:PPO), under
    which every step far from the goal adds (gamma - 1) phi > 0."""
    average_corner_potentials: bool = True
    """True: phi_r is the mean over the 8 bounding-box corners of -log(c_g d_i + 1) (the
    authors' code, rewards.py:110-112); False: -log(c_g d_og + 1) of the mean distance
    (paper)."""
    hand_object_distance: HandObjectDistance = "centre"
    """d_ho from the end-effector tip to the object's centre (the authors' code), or to the
    nearest point of its bounding box ("bbox", 0 inside it; the paper's words allow both)."""
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
    "paper": TaskConfig(
        success_radius=0.1,
        shaping_gamma=0.99,
        average_corner_potentials=False,
        hand_object_distance="bbox",
    ),
    "code": TaskConfig(),
}
"""Named task variants: the paper's MDP, and the authors' released code where it differs."""
