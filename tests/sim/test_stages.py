"""Training stages: each is a valid SimConfig, and the easy stage draws what it promises."""

from __future__ import annotations

import typing

import numpy as np
import pytest

from hamnet.sim.env import VectorEnv
from hamnet.sim.stages import STAGES, StageName, stage_config, stage_in
from hamnet.task.cuboids import CUBOID_NAMES


@pytest.mark.parametrize("name", sorted(STAGES))
def test_every_stage_steps(name: str) -> None:
    env = VectorEnv(stage_config(name, num_envs=2, num_objects=2, nthread=1))
    observation = env.reset(seed=0)
    assert np.isfinite(observation.q).all()


@pytest.mark.parametrize(
    ("name", "closest", "farthest", "radius"),
    [("easy", 0.15, 0.25, 0.1), ("easy-5cm", 0.08, 0.2, 0.05)],
)
def test_easy_stages_are_flat_open_tables_with_near_starts_and_short_pushes(
    name: str, closest: float, farthest: float, radius: float
) -> None:
    """Starts and goals `closest`-`farthest` apart on one flat table top with the same
    orientation, nothing but plates active, every start near the object: a success cannot
    come without pushing it (at least 5 cm on the easy stage), and needs no turning."""
    env = VectorEnv(stage_config(name, num_envs=16, num_objects=4, nthread=1))
    observation = env.reset(seed=3)
    scenes = env.scenes()
    distance = np.linalg.norm(scenes.goal_pose[:, :3] - scenes.start_pose[:, :3], axis=1)
    assert (distance >= closest - 1e-6).all() and (distance <= farthest + 1e-6).all()
    assert closest - radius >= 0.05 - 1e-9 or name == "easy-5cm"
    raised = [
        i for i, name in enumerate(CUBOID_NAMES) if name.startswith(("ramp", "wall", "ceiling"))
    ]
    assert not scenes.cuboid_active[:, raised].any()  # no ramp joins a raised plate: flat
    np.testing.assert_allclose(
        np.abs((scenes.goal_pose[:, 3:] * scenes.start_pose[:, 3:]).sum(1)), 1.0, atol=1e-5
    )
    np.testing.assert_allclose(
        scenes.goal_pose[:, 2], scenes.start_pose[:, 2], atol=1e-4
    )  # same face, flat
    assert env.schedule.p_near_init == 1.0
    assert env.config.task.success_radius == radius and env.config.task.success_angle == 0.3
    assert observation.episode_step.tolist() == [0] * 16
    assert env.config.task.timeout == 100
    # The paddle starts on the side away from the goal (within near_behind of straight
    # behind; the IK's tolerance and fallbacks loosen it a little).
    away = scenes.start_pose[:, :2] - scenes.goal_pose[:, :2]
    paddle = observation.ee_pos_rot6d[:, :2] - scenes.start_pose[:, :2]
    cosine = (away * paddle).sum(1) / np.linalg.norm(away, axis=1) / np.linalg.norm(paddle, axis=1)
    assert np.median(cosine) > np.cos(0.5) and (cosine > 0).mean() >= 0.8


def test_the_easy_stage_has_one_table_and_easy_5cm_draws_them() -> None:
    """The easy stage fixes the table's size and height (issue 28); easy-5cm keeps drawing
    them from the authors' ranges."""
    fixed = VectorEnv(stage_config("easy", num_envs=8, num_objects=2, nthread=1))
    fixed.reset(seed=1)
    drawn = VectorEnv(stage_config("easy-5cm", num_envs=8, num_objects=2, nthread=1))
    drawn.reset(seed=1)
    table = CUBOID_NAMES.index("table")
    tables = [
        np.concatenate(
            [env.scenes().cuboid_half_extent[:, table], env.scenes().cuboid_centre[:, table]], 1
        )
        for env in (fixed, drawn)
    ]
    assert np.ptp(tables[0], axis=0).max() < 1e-9
    assert np.ptp(tables[1], axis=0).max() > 0.01


def test_an_unknown_stage_names_the_known_ones() -> None:
    with pytest.raises(ValueError, match="easy"):
        stage_config("hard")


def test_the_stage_names_are_the_registered_stages() -> None:
    assert set(typing.get_args(StageName)) == set(STAGES)


def test_stage_in_reads_the_stage_a_command_line_picks() -> None:
    """`--stage` is read before the full parse (its stage sets every other flag's default);
    an unknown name falls back to the default, for the full parse to report."""
    assert stage_in(["--num-envs", "4", "--stage", "easy"], "full") == "easy"
    assert stage_in(["--stage=easy"], "full") == "easy"
    assert stage_in([], "easy") == "easy"
    assert stage_in(["--stage", "nope"], "full") == "full"
