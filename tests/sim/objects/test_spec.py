"""Objects in a MuJoCo model built with MjSpec: compile, inertia, shared meshes, simulation."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hamnet.sim.objects import ObjectAsset, ObjectSet, add_object, restitution_solref
from hamnet.sim.objects.asset import StablePoses
from hamnet.sim.objects.mesh import Mesh, box_mesh, unit_inertia


def scene(objects: list[tuple[ObjectAsset, float]], timestep: float = 0.0125) -> mujoco.MjModel:
    """A plane and each (object, scale) resting in its most probable orientation, 0.5 m apart."""
    spec = mujoco.MjSpec()
    spec.option.timestep = timestep
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    for i, (asset, scale) in enumerate(objects):
        height = asset.resting_heights[0] * scale
        add_object(
            spec,
            asset,
            f"object{i}",
            scale=scale,
            mass=0.25,
            friction=0.5,
            restitution=0.1,
            pos=(0.5 * i, 0.0, height + 0.01),
            quat=asset.orientations[0],
        )
    return spec.compile()


def test_model_with_several_objects_compiles_and_simulates(one_of_each: ObjectSet) -> None:
    objects = [(asset, scale) for asset in one_of_each for scale in (0.8, 1.3)]
    model = scene(objects)
    data = mujoco.MjData(model)
    for _ in range(160):  # 2 s
        mujoco.mj_step(model, data)
    poses = data.qpos.reshape(-1, 7)  # (N, 7)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    heights = np.array([a.resting_heights[0] * s for a, s in objects])
    np.testing.assert_allclose(poses[:, 2], heights, atol=5e-3)  # resting, not sunk or flung
    assert np.abs(data.qvel.reshape(-1, 6)[:, :3]).max() < 0.05  # not sliding or falling


def test_body_inertia_is_the_scaled_solid(one_of_each: ObjectSet) -> None:
    asset, scale = one_of_each["mug-s0-0006"], 1.3
    model = scene([(asset, scale)])
    body = model.body("object0")
    assert body.mass[0] == pytest.approx(0.25)
    expected = np.linalg.eigvalsh(0.25 * scale**2 * asset.unit_inertia)  # principal moments
    np.testing.assert_allclose(np.sort(body.inertia), expected, rtol=1e-6)
    np.testing.assert_allclose(body.ipos, 0.0, atol=1e-9)  # the body origin is the centre of mass


def test_parts_collide_and_the_visual_surface_does_not(one_of_each: ObjectSet) -> None:
    asset = one_of_each["mug-s0-0006"]
    model = scene([(asset, 1.0), (asset, 1.0), (asset, 1.5)])
    geoms = [
        model.geom(i)
        for i in range(model.ngeom)
        if model.geom(i).bodyid[0] == model.body("object0").id
    ]
    colliding = [g for g in geoms if g.contype[0] or g.conaffinity[0]]
    assert len(colliding) == len(asset.parts) and len(geoms) == len(asset.parts) + 1
    # Two bodies of the same object and scale share mesh assets; another scale has its own.
    assert model.nmesh == 2 * (len(asset.parts) + 1)


def test_restitution_solref_inverts_the_damped_spring() -> None:
    restitution = np.array([0.0, 0.1, 0.5, 0.9])
    solref = restitution_solref(restitution, timeconst=0.03)  # (4, 2)
    assert solref.shape == (4, 2) and np.all(solref[:, 0] == 0.03)
    zeta = solref[:, 1]
    assert zeta[0] == 1.0  # MuJoCo's default: no bounce
    np.testing.assert_allclose(
        np.exp(-np.pi * zeta[1:] / np.sqrt(1 - zeta[1:] ** 2)), restitution[1:]
    )


def cube(side: float = 0.1) -> ObjectAsset:
    mesh = box_mesh(np.full(3, -side / 2), np.full(3, side / 2))
    stable = StablePoses(
        np.array([[1.0, 0, 0, 0]]), np.ones(1), np.full(1, side / np.sqrt(2)), np.full(1, side / 2)
    )
    return ObjectAsset("cube", mesh, (mesh,), mesh.volume, unit_inertia(mesh), stable, "test")


def rebound(restitution: float) -> float:
    """Largest upward over largest downward speed of a cube dropped from 0.25 m."""
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    add_object(spec, cube(), "cube", pos=(0, 0, 0.3), restitution=restitution)
    model = spec.compile()
    data = mujoco.MjData(model)
    down = up = 0.0
    for _ in range(500):
        mujoco.mj_step(model, data)
        down, up = min(down, data.qvel[2]), max(up, data.qvel[2])
    return up / -down


def test_higher_restitution_bounces_higher() -> None:
    """MuJoCo's soft contacts only approximate the mapping (some rebound even at 0), but
    bounciness must grow with restitution."""
    bounces = [rebound(e) for e in (0.0, 0.2, 0.5)]
    assert bounces[0] < bounces[1] < bounces[2]


def test_mesh_rejects_wrong_shapes() -> None:
    with pytest.raises(ValueError):
        Mesh(np.zeros((4, 2)), np.zeros((1, 3)))
