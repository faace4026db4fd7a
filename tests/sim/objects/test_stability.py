"""Stable resting orientations: really stable in MuJoCo, with the right height and radius."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hamnet.sim import quaternion
from hamnet.sim.objects import ObjectAsset, ObjectSet, StabilityConfig, add_object
from hamnet.sim.objects.build import finish
from hamnet.sim.objects.config import ObjectLibraryConfig
from hamnet.sim.objects.mesh import box_mesh, unit_inertia
from hamnet.sim.objects.stability import (
    angle_between,
    down_directions,
    merge,
    survives_tilt,
    tilt_quaternions,
)

BOX = np.array([0.06, 0.10, 0.16])  # extents, m


def release(
    asset: ObjectAsset, friction: float, timestep: float, seconds: float = 2.0
) -> np.ndarray:
    """Final (K, 7) free-joint poses of the object released at each of its stable poses."""
    spec = mujoco.MjSpec()
    spec.option.timestep = timestep
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], friction=[0, 0, 0])
    for k, (quat, height) in enumerate(zip(asset.orientations, asset.resting_heights)):
        add_object(
            spec,
            asset,
            f"pose{k}",
            pos=(k, 0, height + 0.002),
            quat=quat,
            friction=friction,
            visual=False,
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(int(seconds / timestep)):
        mujoco.mj_step(model, data)
    return data.qpos.reshape(-1, 7).copy()


@pytest.mark.parametrize("friction", [0.2, 1.0])
@pytest.mark.parametrize("timestep", [0.0125, 0.002])
def test_released_at_a_stable_orientation_the_object_stays(
    one_of_each: ObjectSet, friction: float, timestep: float
) -> None:
    """Each stored pose, released at its resting height, keeps its orientation and height."""
    stable_angle = StabilityConfig().stable_angle
    for asset in one_of_each:
        final = release(asset, friction, timestep)  # (K, 7)
        drift = angle_between(
            down_directions(final[:, 3:]), down_directions(asset.orientations)
        )  # (K,)
        assert np.all(drift < stable_angle), (asset.name, drift)
        np.testing.assert_allclose(
            final[:, 2], asset.resting_heights, atol=3e-3, err_msg=asset.name
        )


def test_planar_radius_matches_the_simulated_rest(one_of_each: ObjectSet) -> None:
    for asset in one_of_each:
        final = release(asset, 0.6, 0.0125)  # (K, 7)
        world = np.einsum(
            "kij,pj->kpi", quaternion.to_matrix(final[:, 3:]), asset.mesh.vertices
        )  # (K, P, 3)
        radius = np.linalg.norm(world[..., :2], axis=-1).max(axis=1)  # (K,)
        np.testing.assert_allclose(radius, asset.planar_radii, atol=5e-3, err_msg=asset.name)


@pytest.fixture(scope="module")
def box_asset() -> ObjectAsset:
    mesh = box_mesh(-BOX / 2, BOX / 2)
    return finish("box", mesh, (mesh,), "test", ObjectLibraryConfig(use_cache=False))


def test_box_rests_on_faces_with_hand_computed_height_and_radius(box_asset: ObjectAsset) -> None:
    heights = box_asset.resting_heights
    half = BOX / 2
    face = np.argmin(np.abs(heights[:, None] - half[None, :]), axis=1)  # (K,) axis pointing down
    np.testing.assert_allclose(heights, half[face], atol=1e-9)
    others = np.array([np.delete(half, axis) for axis in face])  # (K, 2)
    np.testing.assert_allclose(box_asset.planar_radii, np.linalg.norm(others, axis=1), atol=1e-9)
    # Flat on the largest face (smallest height) is the likeliest rest, on either side.
    assert list(face[:2]) == [0, 0]
    assert np.all(np.diff(box_asset.stable.probabilities) <= 0)


def test_orientations_are_yaw_free_unit_quaternions(one_of_each: ObjectSet) -> None:
    """Placement composes a stable orientation with a yaw; the stored one carries none."""
    for asset in one_of_each:
        quat = asset.orientations
        np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-9)
        np.testing.assert_allclose(quat[:, 3], 0.0, atol=1e-9)  # rotation axis is horizontal


def test_tilt_check_rejects_a_box_balanced_on_its_edge() -> None:
    """A box standing on an edge, centre of mass right above it, is an equilibrium but not a
    stable one; flat on a face it is."""
    mesh = box_mesh(-BOX / 2, BOX / 2)
    on_face = np.array([1.0, 0.0, 0.0])
    on_edge = np.array([BOX[0], 0.0, BOX[2]]) / np.linalg.norm(
        [BOX[0], BOX[2]]
    )  # towards the +x+z edge
    down = np.stack([on_face, on_edge])  # (2, 3)
    check = survives_tilt(
        (mesh,), unit_inertia(mesh), down, StabilityConfig(), np.random.default_rng(0)
    )
    assert check.tolist() == [True, False]


def test_tilt_quaternion_takes_down_to_minus_z() -> None:
    down = np.random.default_rng(0).normal(size=(16, 3))
    down /= np.linalg.norm(down, axis=1, keepdims=True)
    down[0] = [0, 0, 1]  # upside down: the degenerate case
    np.testing.assert_allclose(down_directions(tilt_quaternions(down)), down, atol=1e-9)


def test_merge_folds_a_nearby_rest_into_the_more_probable_one() -> None:
    z, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    near_z = np.array([np.sin(0.05), 0.0, np.cos(0.05)])
    down, probability = merge(np.stack([z, near_z, x]), np.array([0.2, 0.3, 0.5]), angle=0.2)
    np.testing.assert_allclose(down, np.stack([x, near_z]))
    np.testing.assert_allclose(probability, [0.5, 0.5])
