"""The FR3 in Rerun, drawn from the MuJoCo model the sim runs (`hamnet.sim.robot`).

The model's primitive geoms (boxes, capsules, cylinders, spheres) are logged once, static,
in their body's frame under `robot/<body>/<kind>`; each drawn step then logs only one
Transform3D per body, posed by forward kinematics (`mj_kinematics` on a private MjData)
from the joint positions q. So a frame costs 9 small transforms, never geometry.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np
import rerun as rr

from hamnet.fr3.model import load_mujoco, robot_qpos_index
from hamnet.sim import quaternion

ROOT = "robot"
"""Entity path of the robot; bodies are `robot/<body name>`."""

XYZW = [1, 2, 3, 0]
"""Column order turning MuJoCo's wxyz quaternions into Rerun's xyzw."""

Geoms = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""(pos (G, 3) m, quat (G, 4) wxyz, size (G, 3) MuJoCo's geom_size, rgba (G, 4) uint8) of G
geoms of one kind in their body's frame."""


def _boxes(pos, quat, size, rgba) -> rr.Boxes3D:
    return rr.Boxes3D(
        centers=pos,
        half_sizes=size,
        quaternions=quat[:, XYZW],
        colors=rgba,
        fill_mode=rr.components.FillMode.Solid,
    )


def _capsules(pos, quat, size, rgba) -> rr.Capsules3D:
    # MuJoCo: centred at pos, half-length size[1] along the geom's z; Rerun: from the
    # translation, `length` along z. Start at the lower cap's centre.
    axis = quaternion.to_matrix(quat)[:, :, 2]  # (G, 3) geom z in the body frame
    start = pos - size[:, 1:2] * axis  # (G, 3)
    return rr.Capsules3D(
        lengths=2 * size[:, 1],
        radii=size[:, 0],
        translations=start,
        quaternions=quat[:, XYZW],
        colors=rgba,
    )


def _cylinders(pos, quat, size, rgba) -> rr.Cylinders3D:
    return rr.Cylinders3D(
        lengths=2 * size[:, 1],
        radii=size[:, 0],
        centers=pos,
        quaternions=quat[:, XYZW],
        colors=rgba,
        fill_mode=rr.components.FillMode.Solid,
    )


def _spheres(pos, quat, size, rgba) -> rr.Ellipsoids3D:
    return rr.Ellipsoids3D(
        centers=pos,
        half_sizes=np.repeat(size[:, :1], 3, axis=1),
        colors=rgba,
        fill_mode=rr.components.FillMode.Solid,
    )


SHAPES: dict[int, tuple[str, Callable[..., object]]] = {
    int(mujoco.mjtGeom.mjGEOM_BOX): ("boxes", _boxes),
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): ("capsules", _capsules),
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): ("cylinders", _cylinders),
    int(mujoco.mjtGeom.mjGEOM_SPHERE): ("spheres", _spheres),
}
"""MuJoCo geom type -> (entity name, Rerun archetype of G geoms of that type)."""


class RobotView:
    """Geometry and forward kinematics of the FR3 for the view."""

    def __init__(self, model: mujoco.MjModel | None = None) -> None:
        """`model`: the FR3 (default: the sim's `assets/fr3.xml`)."""
        self.model = model if model is not None else load_mujoco()
        self.data = mujoco.MjData(self.model)
        self.qpos_index = robot_qpos_index(self.model)  # (J,)
        self.bodies = np.unique(self.model.geom_bodyid[self.model.geom_bodyid > 0])  # (N,)
        self.paths = [f"{ROOT}/{self.model.body(int(b)).name}" for b in self.bodies]
        unknown = set(self.model.geom_type.tolist()) - set(SHAPES)
        if unknown:
            raise ValueError(
                f"the robot model has geom types {sorted(unknown)} the view cannot draw"
            )

    def body_poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World poses of the bodies that carry geoms.

        Args:
            q: (J,) joint positions, rad.
        Returns:
            positions (N, 3) m and orientations (N, 4) wxyz, in the order of `paths`.
        """
        self.data.qpos[self.qpos_index] = q
        mujoco.mj_kinematics(self.model, self.data)
        return self.data.xpos[self.bodies].copy(), self.data.xquat[self.bodies].copy()

    def geoms(self, body: int) -> dict[str, Geoms]:
        """The geoms of `body` grouped by entity name (see `Geoms`)."""
        m = self.model
        grouped: dict[str, Geoms] = {}
        for kind, (name, _) in SHAPES.items():
            ids = np.flatnonzero((m.geom_bodyid == body) & (m.geom_type == kind))  # (G,)
            if len(ids):
                rgba = np.round(255 * m.geom_rgba[ids]).astype(np.uint8)  # (G, 4)
                grouped[name] = (m.geom_pos[ids], m.geom_quat[ids], m.geom_size[ids], rgba)
        return grouped

    def log_geometry(self, recording: rr.RecordingStream) -> None:
        """Log every geom once (static), in its body's frame."""
        archetypes = {name: build for name, build in SHAPES.values()}
        for body, path in zip(self.bodies, self.paths, strict=True):
            for name, geoms in self.geoms(int(body)).items():
                recording.log(f"{path}/{name}", archetypes[name](*geoms), static=True)

    def log_pose(self, q: np.ndarray, recording: rr.RecordingStream) -> None:
        """Pose every body for joint positions `q` (J,) rad, at the recording's current time."""
        positions, quats = self.body_poses(q)  # (N, 3), (N, 4)
        for path, position, quat in zip(self.paths, positions, quats[:, XYZW], strict=True):
            recording.log(path, rr.Transform3D(translation=position, quaternion=quat))
