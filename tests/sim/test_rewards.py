"""Reward terms: bounding-box and hand-object distances, log potentials, shaping that
telescopes, the (B, 3) float32 layout, against hand-computed values."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from hamnet.sim import quaternion
from hamnet.sim.rewards import (
    Potentials,
    bbox_corners,
    bbox_from_half_extent,
    corner_distances,
    goal_distance,
    goal_potential,
    hand_object_distance,
    log_potential,
    potentials,
    reward_terms,
    shaping_reward,
)
from hamnet.sim.task_config import TASK_PRESETS, TaskConfig
from hamnet.task.rewards import REWARD_NAMES

SIM_PROTO = Path(__file__).resolve().parents[2] / "proto" / "sim.proto"
"""Where the Transition message documents the reward terms' column order."""
PAPER = TASK_PRESETS["paper"]
CODE = TASK_PRESETS["code"]
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])


def yaw(angle: float) -> np.ndarray:
    """(4,) wxyz rotation by `angle` about world z."""
    return quaternion.from_axis_angle(Z, np.asarray(angle))


def batch(*rows: np.ndarray) -> np.ndarray:
    return np.stack([np.asarray(row, dtype=np.float64) for row in rows])


def test_reward_names_match_the_proto_order() -> None:
    """The Transition message carries `reward_terms` in the column order sim.proto documents
    (success, goal-reaching, contact-inducing) with `reward_names` beside it. Comparing the
    constant with a literal only checked itself: now the proto's list must give the same
    order, and each term fired alone (B = 3: success; goal potential rises; contact
    potential rises) must land in the column its name gives, so reordering the names, the
    columns of `reward_terms` or the proto's list fails here."""
    assert REWARD_NAMES == ("success", "goal", "contact")
    listed = re.search(r"float32 reward terms \(([^)]*)\)", SIM_PROTO.read_text()).group(1)
    assert tuple(term.strip().split("-")[0] for term in listed.split(",")[:3]) == REWARD_NAMES
    success = np.array([True, False, False])
    prev = Potentials(goal=np.array([0.0, -0.5, 0.0]), contact=np.array([0.0, 0.0, -0.5]))
    curr = Potentials(goal=np.zeros(3), contact=np.zeros(3))
    terms = reward_terms(success, prev, curr, CODE)  # gamma = 1: unchanged potentials pay 0
    fired = [[REWARD_NAMES[column] for column in np.flatnonzero(row)] for row in terms]
    assert fired == [["success"], ["goal"], ["contact"]]


def test_bbox_corners_are_the_eight_min_max_combinations() -> None:
    bbox = batch([[-1.0, -2.0, -3.0], [1.0, 2.0, 3.0]])  # (1, 2, 3)
    corners = bbox_corners(bbox)[0]  # (8, 3)
    expected = {(x, y, z) for x in (-1, 1) for y in (-2, 2) for z in (-3, 3)}
    assert corners.shape == (8, 3)
    assert {tuple(c) for c in corners} == expected
    np.testing.assert_array_equal(bbox_from_half_extent(np.array([[1.0, 2.0, 3.0]])), bbox)


def test_corner_distances_by_hand_for_four_poses() -> None:
    """B = 4: at the goal; shifted by (0.3, 0.4, 0); turned by pi about z (every corner of a
    0.06 x 0.08 box moves 2 * sqrt(0.03^2 + 0.04^2) = 0.1); an off-centre box (x in [0, 0.2],
    flat in y and z) turned by pi: four corners stay, four move 0.4, mean 0.2."""
    half = np.array([0.03, 0.04, 0.05])
    bbox = np.stack(
        [
            bbox_from_half_extent(half[None])[0],
            bbox_from_half_extent(half[None])[0],
            bbox_from_half_extent(half[None])[0],
            np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]]),
        ]
    )  # (4, 2, 3)
    goal_pos = batch([0.5, 0.0, 0.1], [0.5, 0.0, 0.1], [0.5, 0.0, 0.1], [0.5, 0.0, 0.1])
    goal_quat = batch(IDENTITY, IDENTITY, IDENTITY, IDENTITY)
    pos = goal_pos + batch([0, 0, 0], [0.3, 0.4, 0.0], [0, 0, 0], [0, 0, 0])
    quat = batch(IDENTITY, IDENTITY, yaw(math.pi), yaw(math.pi))

    distance = corner_distances(pos, quat, goal_pos, goal_quat, bbox)  # (4, 8)
    assert distance.shape == (4, 8)
    np.testing.assert_allclose(distance[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(distance[1], 0.5)
    np.testing.assert_allclose(distance[2], 0.1)
    np.testing.assert_allclose(np.sort(distance[3]), [0, 0, 0, 0, 0.4, 0.4, 0.4, 0.4], atol=1e-12)
    np.testing.assert_allclose(goal_distance(distance), [0.0, 0.5, 0.1, 0.2], atol=1e-12)

    # Paper: phi_r = -log(3 d_og + 1); code: mean over corners of -log(3 d_i + 1).
    paper = goal_potential(distance, PAPER)
    np.testing.assert_allclose(
        paper, [0.0, -math.log(2.5), -math.log(1.3), -math.log(1.6)], atol=1e-12
    )
    code = goal_potential(distance, CODE)
    np.testing.assert_allclose(
        code, [0.0, -math.log(2.5), -math.log(1.3), -0.5 * math.log(2.2)], atol=1e-12
    )


def test_log_potential_is_zero_at_contact_and_falls_with_distance() -> None:
    distance = np.array([0.0, 0.1, 1.0])
    np.testing.assert_allclose(log_potential(distance, 3.0), [0.0, -math.log(1.3), -math.log(4.0)])


def test_hand_object_distance_to_the_box_and_to_the_centre() -> None:
    """B = 4 tips near a box: beside a face (0.2), off an edge (sqrt(0.02)), inside (0), and
    beside a box turned by 90 degrees about z whose long side (0.2) now faces +x (0.3)."""
    bbox = np.stack(
        [bbox_from_half_extent(np.array([[0.1, 0.1, 0.1]]))[0]] * 3
        + [bbox_from_half_extent(np.array([[0.1, 0.2, 0.05]]))[0]]
    )  # (4, 2, 3)
    pos = np.zeros((4, 3))
    quat = batch(IDENTITY, IDENTITY, IDENTITY, yaw(math.pi / 2))
    tip = batch([0.3, 0.0, 0.0], [0.2, 0.2, 0.0], [0.05, -0.05, 0.02], [0.5, 0.0, 0.0])

    box = hand_object_distance(tip, pos, quat, bbox, PAPER)
    np.testing.assert_allclose(box, [0.2, math.sqrt(0.02), 0.0, 0.3], atol=1e-12)
    centre = hand_object_distance(tip, pos, quat, bbox, CODE)
    np.testing.assert_allclose(centre, [0.3, math.sqrt(0.08), math.sqrt(0.0054), 0.5])


def test_potentials_of_four_states() -> None:
    bbox = np.stack([bbox_from_half_extent(np.array([[0.05, 0.05, 0.05]]))[0]] * 4)
    goal_pos = np.zeros((4, 3))
    goal_quat = batch(*[IDENTITY] * 4)
    pos = batch([0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.3])
    tip = pos + batch([0.05, 0, 0], [0.15, 0, 0], [0, 0, 0.35], [0, 0, 0])
    phi = potentials(pos, goal_quat, goal_pos, goal_quat, bbox, tip, PAPER)
    np.testing.assert_allclose(phi.goal, -np.log1p(3.0 * np.array([0.0, 0.1, 0.2, 0.3])))
    np.testing.assert_allclose(phi.contact, -np.log1p(3.0 * np.array([0.0, 0.1, 0.3, 0.0])))


def test_reward_terms_by_hand() -> None:
    """B = 4 steps: success; goal potential rises; contact potential falls; nothing moves.
    Columns are r_s, 0.15 (0.99 phi_r' - phi_r), 0.03 (0.99 phi_c' - phi_c)."""
    success = np.array([True, False, False, False])
    prev = Potentials(goal=np.array([-0.2, -0.5, 0, -0.1]), contact=np.array([0, 0, -0.1, -0.3]))
    curr = Potentials(goal=np.array([0.0, -0.3, 0, -0.1]), contact=np.array([0, 0, -0.4, -0.3]))
    terms = reward_terms(success, prev, curr, PAPER)
    assert terms.shape == (4, 3) and terms.dtype == np.float32
    expected = np.array(
        [
            [1.0, 0.15 * 0.2, 0.0],
            [0.0, 0.15 * (0.99 * -0.3 + 0.5), 0.0],
            [0.0, 0.0, 0.03 * (0.99 * -0.4 + 0.1)],
            [0.0, 0.15 * 0.01 * 0.1, 0.03 * 0.01 * 0.3],
        ]
    )
    np.testing.assert_allclose(terms, expected, rtol=1e-6, atol=1e-9)
    # gamma = 1 (authors' code): a state that does not move earns no shaping.
    np.testing.assert_array_equal(reward_terms(success, prev, prev, CODE)[:, 1:], 0.0)


@pytest.mark.parametrize("gamma", [0.99, 1.0])
def test_shaping_telescopes_over_a_trajectory(gamma: float) -> None:
    """sum_t gamma^t lambda (gamma phi_{t+1} - phi_t) = lambda (gamma^T phi_T - phi_0), so
    shaping cannot change which policy is optimal; a broken sign or a missing gamma on
    phi(s') leaves a residue that grows with T."""
    rng = np.random.default_rng(0)
    num_steps, num_envs = 50, 4
    phi = -rng.uniform(0.0, 2.0, size=(num_steps + 1, num_envs, 2))  # (T + 1, B, 2)
    config = TaskConfig(shaping_gamma=gamma)
    discount = gamma ** np.arange(num_steps)  # (T,)
    total = np.zeros((num_envs, 2))
    for t in range(num_steps):
        prev = Potentials(goal=phi[t, :, 0], contact=phi[t, :, 1])
        curr = Potentials(goal=phi[t + 1, :, 0], contact=phi[t + 1, :, 1])
        total += discount[t] * reward_terms(np.zeros(num_envs, bool), prev, curr, config)[:, 1:]
    expected = np.array([config.lambda_r, config.lambda_c]) * (gamma**num_steps * phi[-1] - phi[0])
    np.testing.assert_allclose(total, expected, rtol=1e-5, atol=1e-6)


def test_shaping_reward_is_gamma_next_minus_current() -> None:
    np.testing.assert_allclose(shaping_reward(np.array([-1.0]), np.array([-0.5]), 0.9), [0.55])


def test_reward_at_the_goal_pays_success_and_no_shaping_from_rest() -> None:
    """An object that sits at its goal with the tip touching it has zero potentials: the
    step pays exactly r_s = 1 and nothing else."""
    bbox = np.stack([bbox_from_half_extent(np.array([[0.05, 0.05, 0.05]]))[0]] * 4)
    pose_pos = np.zeros((4, 3))
    pose_quat = batch(*[IDENTITY] * 4)
    phi = potentials(pose_pos, pose_quat, pose_pos, pose_quat, bbox, pose_pos, PAPER)
    terms = reward_terms(np.ones(4, bool), phi, phi, PAPER)
    np.testing.assert_array_equal(terms, np.tile([1.0, 0.0, 0.0], (4, 1)).astype(np.float32))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"lambda_r": -0.1},
        {"c_g": 0.0},
        {"shaping_gamma": 0.0},
        {"shaping_gamma": 1.5},
        {"hand_object_distance": "tip"},
        {"success_radius": 0.0},
        {"timeout": 0},
        {"drop_depth": -0.1},
    ],
)
def test_task_config_rejects_invalid_values(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        TaskConfig(**kwargs)


def push_returns(config: TaskConfig, steps: int = 30) -> tuple[float, float]:
    """Undiscounted shaping returns (goal, contact) of a typical 0.15 m push: a 0.1 m cube
    slides straight to its goal in `steps` policy steps, the paddle's tip starting 0.15 m
    from its centre and then pushing on its back face (0.05 m from the centre)."""
    t = np.linspace(0.0, 1.0, steps + 1)  # (T + 1,)
    goal = np.array([0.6, 0.0, 0.05])
    pos = goal + np.outer(0.15 * (1.0 - t), [-1.0, 0.0, 0.0])  # (T + 1, 3)
    tip = pos + np.outer(np.minimum(0.15, 0.05 + 0.1 * (1.0 - 10 * t).clip(0)), [-1.0, 0, 0])
    n = len(t)
    phi = potentials(
        pos, np.tile(IDENTITY, (n, 1)), np.tile(goal, (n, 1)), np.tile(IDENTITY, (n, 1)),
        np.tile(bbox_from_half_extent(np.full((1, 3), 0.05)), (n, 1, 1)), tip, config,
    )  # fmt: skip
    prev = Potentials(phi.goal[:-1], phi.contact[:-1])  # (T,) each
    curr = Potentials(phi.goal[1:], phi.contact[1:])
    terms = reward_terms(np.zeros(steps, dtype=bool), prev, curr, config)  # (T, 3)
    return float(terms[:, 1].sum()), float(terms[:, 2].sum())


def test_a_015_m_push_earns_the_authors_shaping_return() -> None:
    """The issue's question: how much shaping does a 0.15 m push earn next to the success
    bonus of 1? With the authors' rewards (the default): the goal term telescopes to
    0.15 * log(1 + 3 * 0.15) = 0.056 (every corner moves 0.15 m), the contact term to
    0.03 * (log(1 + 3 * 0.15) - log(1 + 3 * 0.05)) = 0.007, about 0.06 in all. The
    paper's reading (discount 0.99 in the shaping) adds (gamma - 1) phi > 0 at every step,
    so it pays more the longer the object stays away: 0.072 here, 0.093 over 100 steps."""
    goal, contact = push_returns(TaskConfig())
    assert goal == pytest.approx(0.15 * math.log(1.45), rel=1e-5)
    assert contact == pytest.approx(0.03 * (math.log(1.45) - math.log(1.15)), rel=1e-5)
    paper_goal, paper_contact = push_returns(PAPER)
    assert paper_goal + paper_contact > goal + contact
    assert paper_goal + paper_contact == pytest.approx(0.072, abs=0.002)
