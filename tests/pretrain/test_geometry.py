"""Contact geometry of the dataset: labels, touching and overlap on boxes whose answers are
known by hand."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.pretrain.convex import convex_part, inside, overlap, touch_distance
from hamnet.sim.objects.mesh import box_mesh

UNIT = convex_part(box_mesh(-0.5 * np.ones(3), 0.5 * np.ones(3)))


def test_points_inside_a_box_are_labelled_and_outside_ones_not() -> None:
    points = np.array([[0.0, 0.0, 0.0], [0.49, -0.49, 0.2], [0.51, 0.0, 0.0], [0.0, 0.0, -0.6]])
    assert inside(points, [UNIT]).tolist() == [True, True, False, False]


def test_a_rotated_and_moved_box_labels_in_its_own_frame() -> None:
    quarter = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    long_box = convex_part(box_mesh(np.array([-1.0, -0.1, -0.1]), np.array([1.0, 0.1, 0.1])))
    posed = long_box.posed(quarter, np.array([0.0, 0.0, 1.0]))  # now long along y, at z = 1
    points = np.array([[0.0, 0.9, 1.0], [0.9, 0.0, 1.0], [0.0, 0.0, 0.0]])
    assert inside(points, [posed]).tolist() == [True, False, False]


@pytest.mark.parametrize("direction", [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
def test_two_unit_boxes_touch_one_side_apart(direction) -> None:
    """Two axis-aligned unit cubes moved along an axis touch at a distance of exactly 1."""
    assert touch_distance([UNIT], [UNIT], np.array(direction)) == pytest.approx(1.0, abs=1e-7)


def test_touching_along_a_diagonal_meets_the_corner() -> None:
    diagonal = np.ones(3) / np.sqrt(3.0)
    assert touch_distance([UNIT], [UNIT], diagonal) == pytest.approx(np.sqrt(3.0), abs=1e-6)


def test_a_line_that_misses_gives_none() -> None:
    far = UNIT.posed(np.eye(3), np.array([0.0, 5.0, 0.0]))
    assert touch_distance([UNIT], [far], np.array([1.0, 0.0, 0.0])) is None


def test_overlap_is_exact_near_the_surface() -> None:
    shifted = lambda x: UNIT.posed(np.eye(3), np.array([x, 0.0, 0.0]))
    assert overlap([UNIT], [shifted(0.999)])
    assert not overlap([UNIT], [shifted(1.001)])
