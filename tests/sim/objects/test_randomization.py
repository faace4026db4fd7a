"""Per-episode physics randomization: ranges, batching, determinism, validation."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.sim.objects import ObjectRandomization, sample_physics


def test_samples_lie_in_the_configured_ranges() -> None:
    config = ObjectRandomization()
    object_radius = np.array([0.05, 0.08, 0.12, 0.2] * 256)  # (B,) library sizes, m
    physics = sample_physics(config, np.random.default_rng(0), object_radius)
    for values in (physics.scale, physics.mass, physics.friction, physics.restitution):
        assert values.shape == object_radius.shape
    radius = physics.scale * object_radius  # what the object is scaled to
    assert radius.min() >= 0.05 and radius.max() <= 0.10
    assert physics.mass.min() >= 0.1 and physics.mass.max() <= 0.5
    assert physics.friction.min() >= 0.2 and physics.friction.max() <= 1.0
    assert physics.restitution.min() >= 0.0 and physics.restitution.max() <= 0.2
    # Uniform, so a big batch covers most of each range.
    assert np.ptp(radius) > 0.045 and np.ptp(physics.mass) > 0.35


def test_scale_range_is_used_without_a_radius_range() -> None:
    config = ObjectRandomization(radius=None, scale=(0.8, 1.2))
    physics = sample_physics(config, np.random.default_rng(1), np.full(512, 0.1))
    assert physics.scale.min() >= 0.8 and physics.scale.max() <= 1.2


def test_same_generator_state_gives_the_same_samples() -> None:
    config = ObjectRandomization()
    a = sample_physics(config, np.random.default_rng(5), np.full(4, 0.1))
    b = sample_physics(config, np.random.default_rng(5), np.full(4, 0.1))
    c = sample_physics(config, np.random.default_rng(6), np.full(4, 0.1))
    assert np.array_equal(a.mass, b.mass) and np.array_equal(a.scale, b.scale)
    assert not np.array_equal(a.mass, c.mass)


@pytest.mark.parametrize(
    "bad",
    [
        dict(mass=(0.5, 0.1)),
        dict(friction=(-0.1, 1.0)),
        dict(restitution=(0.0, 1.5)),
        dict(radius=(0.0, 0.1)),
    ],
)
def test_invalid_ranges_are_rejected(bad: dict) -> None:
    with pytest.raises(ValueError):
        ObjectRandomization(**bad)
