"""The FR3 model file, shared by MuJoCo and Pinocchio, and end-effector kinematics from it.

One MJCF file (`assets/fr3.xml`, written from published facts, see its header) feeds both
MuJoCo (simulation) and Pinocchio (safety's Cartesian clipping), so the two agree on the
end-effector pose and Jacobian by construction; tests/fr3/test_model.py checks that they do.
"""

from __future__ import annotations

import functools
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from hamnet.fr3.limits import JOINT_NAMES

ACTUATOR_NAMES = tuple(f"fr3_motor{i}" for i in range(1, 8))
"""Torque motors, one per joint, same order as JOINT_NAMES."""

EE_SITE = "ee"
"""Site (MuJoCo) and frame (Pinocchio) at the centre of the paddle's contact face."""

PADDLE_BODY = "fr3_paddle"
"""Body of the paddle that replaces the gripper (its tube and plate)."""

PADDLE_PLATE_GEOM = "fr3_paddle_plate"
"""The paddle's plate: a box whose axes are the `EE_SITE` frame's, its outer face at the site."""

ROBOT_CONTYPE = 2
"""contype of every robot geom: scene geoms (contype 1) do not match it..."""

ROBOT_CONAFFINITY = 1
"""...but robot geoms accept contype 1, so robot-scene pairs collide and robot-robot do not."""


def model_path() -> Path:
    """Path of the FR3 MJCF file, shipped as package data of `hamnet.fr3`."""
    return Path(__file__).resolve().parent / "assets" / "fr3.xml"


def load_mujoco() -> mujoco.MjModel:
    """The FR3 as a MuJoCo model (robot only; scenes add their geoms through MjSpec)."""
    return mujoco.MjModel.from_xml_path(str(model_path()))


@functools.cache
def paddle_plate_half_extents() -> np.ndarray:
    """(2,) the plate's half extents along the ee frame's x and y axes, m: how far the plate
    reaches past the ee site sideways (what a pusher keeps clear of the object it steps
    behind). Read-only: every caller shares the cached array."""
    half = load_mujoco().geom(PADDLE_PLATE_GEOM).size[:2].copy()
    half.flags.writeable = False
    return half


def load_pinocchio() -> tuple[pin.Model, pin.Data]:
    """The FR3 as a Pinocchio model and a matching data, from the same file."""
    model = pin.buildModelFromMJCF(str(model_path()))
    return model, model.createData()


def robot_qpos_index(model: mujoco.MjModel) -> np.ndarray:
    """qpos addresses of the robot joints, (J,), also in a model with scene bodies added."""
    return np.array([model.joint(name).qposadr[0] for name in JOINT_NAMES])


def robot_dof_index(model: mujoco.MjModel) -> np.ndarray:
    """qvel (dof) addresses of the robot joints, (J,)."""
    return np.array([model.joint(name).dofadr[0] for name in JOINT_NAMES])


def ee_pos_rot6d(position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """The end effector as RobotState carries it (sim and bridge alike): (..., 9) of the
    position (..., 3), m, and the first two columns of the rotation (..., 3, 3), column after
    column (the 6D rotation the policy reads). Not a `*_pose`: those are position +
    quaternion wxyz (7); nor a `*_placement`: that is position and the whole rotation matrix."""
    six_d = np.swapaxes(rotation[..., :, :2], -1, -2).reshape(*rotation.shape[:-2], 6)
    return np.concatenate([position, six_d], axis=-1)


def mujoco_ee_placement(
    model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector placement (position and rotation matrix, Pinocchio's word for an SE3) in
    the world by MuJoCo.

    Args:
        model: a model holding the FR3 (alone or in a scene).
        data: scratch data for `model`; its robot qpos is overwritten with `q`.
        q: joint positions, (J,), rad.
    Returns:
        position (3,) in m and rotation matrix (3, 3) of site `ee`.
    """
    data.qpos[robot_qpos_index(model)] = q
    mujoco.mj_kinematics(model, data)
    site = model.site(EE_SITE).id
    return data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()


def mujoco_ee_jacobian(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray) -> np.ndarray:
    """End-effector Jacobian by MuJoCo, world-aligned at site `ee`.

    Args:
        model, data: as in `mujoco_ee_placement` (data is scratch).
        q: joint positions, (J,), rad.
    Returns:
        (6, J): rows 0-2 linear velocity (m/s), rows 3-5 angular velocity (rad/s) per rad/s.
    """
    data.qpos[robot_qpos_index(model)] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, model.site(EE_SITE).id)
    return np.vstack([jacp, jacr])[:, robot_dof_index(model)]


def pinocchio_ee_placement(
    model: pin.Model, data: pin.Data, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector placement in the world by Pinocchio: position (3,) m, rotation (3, 3)."""
    pin.framesForwardKinematics(model, data, q)
    placement = data.oMf[model.getFrameId(EE_SITE)]
    return placement.translation.copy(), placement.rotation.copy()


def pinocchio_ee_jacobian(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """End-effector Jacobian by Pinocchio, (6, J), same convention as `mujoco_ee_jacobian`."""
    frame = model.getFrameId(EE_SITE)
    return pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED).copy()
