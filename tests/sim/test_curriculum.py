"""Curriculum: endpoints, linear interpolation, monotone direction, schedule names and the
hand-off to SceneConfig.p_tight."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.sim.curriculum import (
    SCHEDULE_NAMES,
    CurriculumConfig,
    curriculum_progress,
    curriculum_values,
    scene_config_at,
)
from hamnet.sim.scene_config import SceneConfig

CONFIG = CurriculumConfig(
    p_near_init_start=0.9, p_near_init_end=0.1, p_tight_start=0.2, p_tight_end=0.6,
    start_step=1_000, num_steps=10_000,
)  # fmt: skip


def test_endpoints_hold_before_and_after_the_schedule() -> None:
    for step in (0, 500, 1_000):
        values = curriculum_values(step, CONFIG)
        assert values.p_near_init == pytest.approx(0.9) and values.p_tight == pytest.approx(0.2)
    for step in (11_000, 50_000):
        values = curriculum_values(step, CONFIG)
        assert values.p_near_init == pytest.approx(0.1) and values.p_tight == pytest.approx(0.6)


def test_values_move_linearly_by_hand() -> None:
    """A quarter of the way (step 3500): 0.9 - 0.25 * 0.8 = 0.7 and 0.2 + 0.25 * 0.4 = 0.3."""
    assert curriculum_progress(3_500, CONFIG) == pytest.approx(0.25)
    values = curriculum_values(3_500, CONFIG)
    assert values.p_near_init == pytest.approx(0.7)
    assert values.p_tight == pytest.approx(0.3)


def test_near_init_falls_and_tight_rises_monotonically() -> None:
    steps = np.linspace(0, 2 * CurriculumConfig().num_steps, 101).astype(int)
    values = [curriculum_values(int(step)) for step in steps]
    near = np.array([v.p_near_init for v in values])
    tight = np.array([v.p_tight for v in values])
    assert np.all(np.diff(near) <= 1e-12) and near[0] > near[-1]
    assert np.all(np.diff(tight) >= -1e-12) and tight[0] < tight[-1]
    assert np.all((near >= 0) & (near <= 1) & (tight >= 0) & (tight <= 1))


def test_default_endpoints_follow_the_authors_weights() -> None:
    """Code weights 0.25 -> 10 (random vs near) and 0.5 -> 5 (tight vs nominal) against 1."""
    start, end = curriculum_values(0), curriculum_values(CurriculumConfig().num_steps)
    assert start.p_near_init == pytest.approx(1 / 1.25) and end.p_near_init == pytest.approx(1 / 11)
    assert start.p_tight == pytest.approx(0.5 / 1.5) and end.p_tight == pytest.approx(5 / 6)


def test_schedule_names_are_stable() -> None:
    assert SCHEDULE_NAMES == ("p_near_init", "p_tight")
    assert list(curriculum_values(0, CONFIG).as_dict()) == list(SCHEDULE_NAMES)


def test_p_tight_feeds_the_scene_config() -> None:
    scene = scene_config_at(curriculum_values(11_000, CONFIG), SceneConfig())
    assert scene.p_tight == pytest.approx(0.6)
    assert scene.p_ceiling == SceneConfig().p_ceiling


@pytest.mark.parametrize(
    "kwargs",
    [{"p_tight_end": 1.5}, {"p_near_init_start": -0.1}, {"num_steps": 0}, {"start_step": -1}],
)
def test_config_rejects_invalid_values(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        CurriculumConfig(**kwargs)
