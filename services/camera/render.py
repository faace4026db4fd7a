"""Render depth views of a sim scene with MuJoCo's offscreen renderer (EGL), from virtual
cameras placed like the paper's four D435s, with a segmentation mask (scene cuboids, object).

`RigRenderer` renders one environment with the arm at any joint positions (the camera
service's `sim` source). MuJoCo picks its OpenGL backend when it is first imported, so this
module must be imported before anything imports mujoco (it sets `MUJOCO_GL=egl` unless set);
the script form runs in a process of its own:

    python -m hamnet.camera.render OUT.npz [--seed N] [--width W --height H]

writes the views and the scene they show (cuboids, object points and pose of environment 0
of a `VectorEnv`), so depth fusion can be compared with the analytic clouds of that scene.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import argparse  # noqa: E402
from typing import Self  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from hamnet.camera.views import OBJECT, SCENE, DepthView, d435_rig  # noqa: E402
from hamnet.sim.config import SimConfig  # noqa: E402
from hamnet.sim.env import VectorEnv  # noqa: E402

D435_FOVY = 58.0
"""Vertical field of view of the D435 depth camera, degrees (87 x 58)."""
FIELDS = ("geom_pos", "geom_quat", "geom_size", "geom_dataid", "geom_rbound", "geom_aabb")


def environment_model(env: VectorEnv, index: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """A model and data showing environment `index` of the batch (its cuboids and object)."""
    model = env.world.model.__copy__()
    for name in FIELDS:
        getattr(model, name)[:] = env.physics.fields[name][index]
    model.vis.global_.fovy = D435_FOVY
    data = mujoco.MjData(model)
    data.qpos[:] = env.physics.qpos[index]
    mujoco.mj_forward(model, data)
    return model, data


def _pose(scene: mujoco.MjvScene) -> np.ndarray:
    """(4, 4) OpenCV camera-to-world pose of the rendered view: MuJoCo keeps two eye cameras
    half the inter-pupillary distance apart and renders a mono view from their average."""
    eyes = scene.camera[0], scene.camera[1]
    forward, up = (
        np.mean([np.array(getattr(e, name)) for e in eyes], 0) for name in ("forward", "up")
    )
    pose = np.eye(4)
    pose[:3, :3] = np.stack([np.cross(forward, up), -up, forward], axis=1)
    pose[:3, 3] = np.mean([np.array(e.pos) for e in eyes], 0)
    return pose


def _intrinsics(gl_camera, width: int, height: int) -> np.ndarray:
    near, top, bottom = gl_camera.frustum_near, gl_camera.frustum_top, gl_camera.frustum_bottom
    fy = height * near / (top - bottom)
    fx = fy  # square pixels: MuJoCo widens the frustum with the aspect ratio
    return np.array([[fx, 0.0, width / 2 - 0.5], [0.0, fy, height / 2 - 0.5], [0.0, 0.0, 1.0]])


class RigRenderer:
    """Depth and segmentation of environment `index` of `env` from the four D435-like
    cameras, with the arm posed at any joint positions (the camera service's sim source
    renders the arm where the robot, simulated or real, reports it). Holds one offscreen
    context: `close` it (or use it as a context manager)."""

    def __init__(self, env: VectorEnv, index: int, width: int, height: int) -> None:
        self.model, self.data = environment_model(env, index)
        self.robot_qpos = env.world.robot_qpos
        table = env.scenes(np.array([index])).cuboid_centre[0, 0]
        self.rig = d435_rig(table)
        self.labels_of = np.zeros(self.model.ngeom + 1, np.uint8)
        self.labels_of[env.world.cuboid_geoms] = SCENE
        self.labels_of[env.world.object_geoms] = OBJECT
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = 1  # the object's parts are in group 3, hidden by default
        self.width, self.height = width, height
        self.renderer = mujoco.Renderer(self.model, height, width)

    def views(self, q: np.ndarray | None = None) -> list[DepthView]:
        """The four views, with the arm at joint positions `q` (J,) rad (None: as reset)."""
        if q is not None:
            self.data.qpos[self.robot_qpos] = q
            mujoco.mj_forward(self.model, self.data)
        renderer, views = self.renderer, []
        for lookat, azimuth, elevation in self.rig:
            camera = mujoco.MjvCamera()
            camera.lookat[:], camera.distance = lookat, float(np.hypot(1.0, 0.7))
            camera.azimuth, camera.elevation = azimuth, elevation
            renderer.update_scene(self.data, camera, scene_option=self.option)
            renderer.enable_depth_rendering()
            depth = renderer.render().copy()
            renderer.disable_depth_rendering()
            renderer.enable_segmentation_rendering()
            segment = renderer.render()
            renderer.disable_segmentation_rendering()
            is_geom = segment[..., 1] == mujoco.mjtObj.mjOBJ_GEOM
            labels = np.where(
                is_geom, self.labels_of[np.clip(segment[..., 0], 0, self.model.ngeom)], 0
            )
            views.append(
                DepthView(
                    depth.astype(np.float32),
                    labels.astype(np.uint8),
                    _intrinsics(renderer.scene.camera[0], self.width, self.height),
                    _pose(renderer.scene),
                )
            )
        return views

    def close(self) -> None:
        """Free the offscreen context."""
        self.renderer.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render_views(env: VectorEnv, index: int, width: int, height: int) -> list[DepthView]:
    """Depth and segmentation of environment `index` from the four D435-like cameras."""
    with RigRenderer(env, index, width, height) as renderer:
        return renderer.views()


def main() -> None:
    """Render environment 0 of a seeded sim and save views and scene to an .npz file."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--width", type=int, default=212)
    parser.add_argument("--height", type=int, default=120)
    args = parser.parse_args()
    env = VectorEnv(SimConfig(num_envs=1, num_objects=2, nthread=1, seed=args.seed))
    obs = env.reset(seed=args.seed)
    views = render_views(env, 0, args.width, args.height)
    arrays = {
        f"{name}_{i}": getattr(v, name)
        for i, v in enumerate(views)
        for name in ("depth", "labels", "intrinsics", "camera_to_world")
    }
    s = env.scenes(np.array([0]))
    scene = {
        "centre": s.cuboid_centre[0],
        "quat": s.cuboid_quat[0],
        "half_extent": s.cuboid_half_extent[0],
        "active": s.cuboid_active[0],
    }
    np.savez(
        args.out,
        **arrays,
        **scene,
        object_points=s.object_points[0],
        object_pose=obs.object_pose[0],
    )


if __name__ == "__main__":
    main()
