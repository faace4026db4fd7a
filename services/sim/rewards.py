"""The paper's three reward terms, batched over B environments, pure numpy.

The reward is r = r_s + lambda_r r_r + lambda_c r_c (paper line 244). r_s = 1_suc is the
sparse success reward; r_r and r_c are potential-based shaping terms gamma phi(s') - phi(s)
(line 245, Ng et al. 1999) with

    phi_r(s) = -log(c_g d_og(s) + 1),   d_og: object-goal bounding-box distance,
    phi_c(s) = -log(c_r d_ho(s) + 1),   d_ho: end-effector tip to object distance.

d_og is the mean distance between corresponding corners of the object's bounding box at its
current and goal poses (the keypoint distance of Allshire et al. 2022, which the paper
cites; the authors' code uses the 8 box corners). The environment keeps the `Potentials`
of the last state: after a reset it stores those of the reset state, so the first step's
shaping measures progress from the start. `reward_terms` returns the weighted terms as
(B, 3) float32 columns named by REWARD_NAMES (the critic has one value head per term; a
row sums to r). Shapes: B environments, P points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.task_config import TaskConfig

_CORNER_SIGNS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
"""(8, 3) which of min (0) or max (1) each corner takes per axis."""


class Potentials(NamedTuple):
    """Shaping potentials of one state, kept by the environment for the next step."""

    goal: np.ndarray
    """(B,) phi_r, <= 0."""
    contact: np.ndarray
    """(B,) phi_c, <= 0."""


def bbox_from_half_extent(half_extent: np.ndarray) -> np.ndarray:
    """Bounding box (B, 2, 3) centred on the object's origin from half extents (B, 3), m."""
    return np.stack([-half_extent, half_extent], axis=-2)


def bbox_corners(bbox: np.ndarray) -> np.ndarray:
    """The 8 corners (B, 8, 3) of object-frame boxes given as min and max corners (B, 2, 3)."""
    return np.where(_CORNER_SIGNS == 1, bbox[:, None, 1, :], bbox[:, None, 0, :])


def to_world(pos: np.ndarray, quat: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Object-frame points (B, P, 3) in the world, for poses pos (B, 3), quat (B, 4) wxyz."""
    rotation = quaternion.to_matrix(quat)  # (B, 3, 3)
    return np.einsum("bij,bpj->bpi", rotation, points) + pos[:, None, :]


def corner_distances(
    pos: np.ndarray,
    quat: np.ndarray,
    goal_pos: np.ndarray,
    goal_quat: np.ndarray,
    bbox: np.ndarray,
) -> np.ndarray:
    """Distance of each bounding-box corner from its place at the goal pose.

    Args:
        pos, quat: (B, 3) m and (B, 4) wxyz, the object's pose.
        goal_pos, goal_quat: (B, 3) m and (B, 4) wxyz, its goal pose.
        bbox: (B, 2, 3) min and max corner of its bounding box in the object frame, m.
    Returns:
        (B, 8) distances, m.
    """
    corners = bbox_corners(bbox)  # (B, 8, 3)
    now = to_world(pos, quat, corners)  # (B, 8, 3)
    goal = to_world(goal_pos, goal_quat, corners)  # (B, 8, 3)
    return np.linalg.norm(now - goal, axis=-1)


def goal_distance(corner_distance: np.ndarray) -> np.ndarray:
    """d_og (B,), m: the mean corner distance (B, 8) of the bounding box (line 245)."""
    return corner_distance.mean(axis=-1)


def log_potential(distance: np.ndarray, scale: float) -> np.ndarray:
    """phi = -log(scale * distance + 1) (line 245), elementwise; 0 at distance 0."""
    return -np.log1p(scale * distance)


def goal_potential(corner_distance: np.ndarray, config: TaskConfig) -> np.ndarray:
    """phi_r (B,) from the corner distances (B, 8), m.

    The paper applies the log to d_og; the authors' code averages the per-corner potentials
    (`config.average_corner_potentials`). Both are 0 at the goal and fall with distance.
    """
    if config.average_corner_potentials:
        return log_potential(corner_distance, config.c_g).mean(axis=-1)
    return log_potential(goal_distance(corner_distance), config.c_g)


def hand_object_distance(
    tip_pos: np.ndarray,
    pos: np.ndarray,
    quat: np.ndarray,
    bbox: np.ndarray,
    config: TaskConfig,
) -> np.ndarray:
    """d_ho (B,), m: from the end-effector tip to the object (line 245).

    Args:
        tip_pos: (B, 3) world position of the end-effector tip (the paddle's site), m.
        pos, quat: (B, 3) m and (B, 4) wxyz, the object's pose.
        bbox: (B, 2, 3) min and max corner of its bounding box in the object frame, m.
        config: "bbox" measures to the box's nearest point (0 inside), "centre" to `pos`.
    """
    offset = tip_pos - pos  # (B, 3), world
    if config.hand_object_distance == "centre":
        return np.linalg.norm(offset, axis=-1)
    local = np.einsum("bji,bj->bi", quaternion.to_matrix(quat), offset)  # (B, 3), R^T offset
    nearest = np.clip(local, bbox[:, 0, :], bbox[:, 1, :])  # (B, 3)
    return np.linalg.norm(local - nearest, axis=-1)


def potentials(
    pos: np.ndarray,
    quat: np.ndarray,
    goal_pos: np.ndarray,
    goal_quat: np.ndarray,
    bbox: np.ndarray,
    tip_pos: np.ndarray,
    config: TaskConfig | None = None,
) -> Potentials:
    """phi_r and phi_c of B states; arguments as in `corner_distances` and
    `hand_object_distance`."""
    config = config if config is not None else TaskConfig()
    corner_distance = corner_distances(pos, quat, goal_pos, goal_quat, bbox)  # (B, 8), m
    d_ho = hand_object_distance(tip_pos, pos, quat, bbox, config)  # (B,), m
    return Potentials(
        goal=goal_potential(corner_distance, config),
        contact=log_potential(d_ho, config.c_r),
    )


def shaping_reward(phi: np.ndarray, next_phi: np.ndarray, gamma: float) -> np.ndarray:
    """gamma phi(s') - phi(s) (line 245), elementwise (B,).

    Its discounted sum over an episode telescopes to gamma^T phi(s_T) - phi(s_0).
    """
    return gamma * next_phi - phi


def success_reward(success: np.ndarray, config: TaskConfig) -> np.ndarray:
    """r_s (B,): `config.success_reward` (1 in the paper) where `success` (B,) bool holds."""
    return np.where(success, config.success_reward, 0.0)


def goal_reward(prev: Potentials, curr: Potentials, config: TaskConfig) -> np.ndarray:
    """lambda_r r_r (B,): the weighted goal-reaching shaping term."""
    return config.lambda_r * shaping_reward(prev.goal, curr.goal, config.shaping_gamma)


def contact_reward(prev: Potentials, curr: Potentials, config: TaskConfig) -> np.ndarray:
    """lambda_c r_c (B,): the weighted contact-inducing shaping term."""
    return config.lambda_c * shaping_reward(prev.contact, curr.contact, config.shaping_gamma)


def reward_terms(
    success: np.ndarray,
    prev: Potentials,
    curr: Potentials,
    config: TaskConfig | None = None,
) -> np.ndarray:
    """The three weighted reward terms of one step s -> s'.

    Args:
        success: (B,) bool, s' is a success (`termination.is_success`).
        prev: potentials of s (of the reset state on an episode's first step).
        curr: potentials of s'.
        config: coefficients; the default is the paper's.
    Returns:
        (B, 3) float32 columns REWARD_NAMES = (r_s, lambda_r r_r, lambda_c r_c); a row sums
        to the paper's r.
    """
    config = config if config is not None else TaskConfig()
    terms = (
        success_reward(success, config),
        goal_reward(prev, curr, config),
        contact_reward(prev, curr, config),
    )
    return np.stack(terms, axis=-1).astype(np.float32)  # (B, 3)
